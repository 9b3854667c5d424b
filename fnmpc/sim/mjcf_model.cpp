// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/sim/mjcf_model.hpp"

#include <array>
#include <cstdio>
#include <cstring>
#include <memory>
#include <mutex>
#include <stdexcept>

namespace fnmpc::sim {

namespace {

void WarningToStderr(const char* message) { std::fprintf(stderr, "MuJoCo warning: %s\n", message); }

}  // namespace

mjModel* CompileMjcf(const std::string& xml, const std::string& who) {
  auto vfs = std::make_unique<mjVFS>();  // ~2 MB: never on the stack
  mj_defaultVFS(vfs.get());
  const char* name = "fnmpc_model.xml";
  if (mj_makeEmptyFileVFS(vfs.get(), name, static_cast<int>(xml.size())) != 0) {
    throw std::runtime_error(who + " cannot create the in-memory MJCF file");
  }
  std::memcpy(vfs->filedata[mj_findFileVFS(vfs.get(), name)], xml.data(), xml.size());
  std::array<char, 1000> err{};
  mjModel* m = nullptr;
  {
    // Stepping needs no lock: each world owns its data.
    static std::mutex compile_mutex;
    const std::lock_guard<std::mutex> lock(compile_mutex);
    if (mju_user_warning == nullptr) mju_user_warning = WarningToStderr;
    m = mj_loadXML(name, vfs.get(), err.data(), static_cast<int>(err.size()));
  }
  mj_deleteVFS(vfs.get());
  if (m == nullptr) throw std::runtime_error(who + " MuJoCo: " + err.data());
  return m;
}

}  // namespace fnmpc::sim
