// SPDX-License-Identifier: BSD-3-Clause
// `fnmpc campaign CAMPAIGN.yaml --executor local|slurm|dask`: a Monte Carlo campaign as shards
// of `fnmpc run --shard I/N` on this machine's cores, a Slurm job array or a Dask cluster,
// merged with `fnmpc merge` (docs/campaigns.md). The executors are Slurm's and Dask's own
// (sbatch, dask.distributed); tools/campaign.py drives them.
#include <csignal>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "apps/fnmpc/commands.hpp"
#include "apps/fnmpc/process.hpp"

namespace fnmpc::app {
namespace {

struct CampaignArgs {
  std::string campaign;
  std::string executor = "local";
  std::string out;
  std::string script = std::string(FNMPC_SOURCE_DIR) + "/tools/campaign.py";
  bool quiet = false;
};

int Campaign(const CampaignArgs& a) {
  std::error_code ec;
  // The shards run this very executable (the same build as the merge).
  const std::string self = std::filesystem::read_symlink("/proc/self/exe", ec).string();
  std::vector<std::string> argv = {"/usr/bin/python3",
                                   a.script,
                                   a.campaign,
                                   "--executor",
                                   a.executor,
                                   "--fnmpc",
                                   ec ? std::string("fnmpc") : self};
  if (!a.out.empty()) argv.insert(argv.end(), {"-o", a.out});
  if (a.quiet) argv.emplace_back("-q");
  const int rc = RunProgram(argv);
  if (rc == 128 + SIGINT || rc == 128 + SIGTERM) throw Interrupted(rc, "campaign interrupted");
  if (rc < 0) throw std::runtime_error(a.script + ": cannot start /usr/bin/python3");
  return rc;
}

void Register(CLI::App& app, std::vector<Command>& registry) {
  auto a = std::make_shared<CampaignArgs>();
  CLI::App* sub = app.add_subcommand(
      "campaign", "Run a Monte Carlo campaign as shards on local cores, Slurm or Dask, merged");
  sub->add_option("campaign", a->campaign, "campaign YAML (docs/campaigns.md)")
      ->required()
      ->check(CLI::ExistingFile);
  sub->add_option("--executor", a->executor,
                  "local (a process per shard on this machine), slurm (a job array through "
                  "sbatch) or dask (dask.distributed: a local cluster or the campaign's "
                  "scheduler)")
      ->check(CLI::IsMember({"local", "slurm", "dask"}))
      ->capture_default_str();
  sub->add_option("-o,--out", a->out, "campaign folder (default: the campaign file's `out`)");
  sub->add_option("--script", a->script, "campaign driver")->check(CLI::ExistingFile);
  sub->add_flag("-q,--quiet", a->quiet, "no progress line");
  registry.push_back({sub, [a] { return Campaign(*a); }});
}
const RegisterCommand kRegistered(&Register);

}  // namespace
}  // namespace fnmpc::app
