// SPDX-License-Identifier: BSD-3-Clause
#include "apps/fnmpc/sysid_report.hpp"

#include "apps/fnmpc/commands.hpp"

#include <fmt/core.h>

#include <csignal>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <stdexcept>

#include "apps/fnmpc/process.hpp"

namespace fnmpc::app::sysid_report {

void WriteCsv(const fs::path& path, const std::vector<std::string>& header,
              const std::vector<std::vector<double>>& columns) {
  std::ofstream out(path);
  if (!out) throw std::runtime_error(path.string() + ": cannot write: " + std::strerror(errno));
  for (std::size_t c = 0; c < header.size(); ++c) out << (c ? "," : "") << header[c];
  out << "\n";
  const std::size_t rows = columns.empty() ? 0 : columns[0].size();
  for (std::size_t r = 0; r < rows; ++r) {
    for (std::size_t c = 0; c < columns.size(); ++c) {
      out << (c ? "," : "") << fmt::format("{:.10g}", columns[c][r]);
    }
    out << "\n";
  }
  out.flush();  // a full disk shows here, not in the destructor
  if (!out) throw std::runtime_error(path.string() + ": write failed: " + std::strerror(errno));
}

fs::path ReportDir(const std::string& out) { return fs::path(out + ".report"); }

void Finalize(const fs::path& tmp, const fs::path& final_dir, bool plots) {
  if (plots) {
    const std::string script = std::string(FNMPC_SOURCE_DIR) + "/tools/sysid_report.py";
    // No shell: the paths go to the script verbatim, whatever characters they hold.
    const int rc = RunProgram({"/usr/bin/python3", script, tmp.string()}, {"MPLBACKEND=Agg"});
    if (rc == 128 + SIGINT || rc == 128 + SIGTERM) {
      // Ctrl-C reaches the plotter too: stop here rather than report success.
      std::error_code ec;
      fs::remove_all(tmp, ec);
      throw Interrupted(rc, script + " interrupted (signal " + std::to_string(rc - 128) + ")");
    }
    if (rc != 0) {
      fmt::print(stderr, "fnmpc: warning: {} failed (status {}); CSVs are in {}\n", script, rc,
                 final_dir.string());
    }
  }
  std::error_code ec;
  fs::remove_all(final_dir, ec);
  fs::rename(tmp, final_dir);
}

fs::path MakeTemp(const fs::path& final_dir) {
  fs::path tmp = final_dir;
  tmp += ".tmp";
  std::error_code ec;
  fs::remove_all(tmp, ec);
  fs::create_directories(tmp);
  return tmp;
}

void PrintStages(const std::vector<Stage>& stages) {
  for (const auto& s : stages) {
    if (!s.ok) {
      fmt::print("  stage {:<15} FAILED: {}\n", s.name, s.reason);
      continue;
    }
    const std::string which = s.FailedChecks();
    fmt::print("  stage {:<15} ok, sanity {}{}\n", s.name, which.empty() ? "PASS" : "FAIL",
               which.empty() ? "" : " (" + which + ")");
  }
}

}  // namespace fnmpc::app::sysid_report
