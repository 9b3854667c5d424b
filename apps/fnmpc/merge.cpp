// SPDX-License-Identifier: BSD-3-Clause
// `fnmpc merge SHARD_DIR... -o OUT`: joins the shard folders of `fnmpc run --shard I/N` into
// the run folder the unsharded run writes (docs/campaigns.md).
#include <fmt/core.h>

#include <memory>
#include <string>
#include <vector>

#include "apps/fnmpc/commands.hpp"
#include "fnmpc/experiment/run_folder.hpp"

namespace fnmpc::app {
namespace {

struct MergeArgs {
  std::vector<std::string> shards;
  std::string out;
  bool overwrite = false;
};

int Merge(const MergeArgs& a) {
  // Checks every shard, writes beside -o and renames into place: a refused or failed merge
  // leaves -o as it was.
  const nlohmann::json summary = experiment::MergeRunFolders(a.shards, a.out, a.overwrite);
  fmt::print("{}\n", a.out);
  const auto failures = summary.value("failures", nlohmann::json::array());
  for (const auto& f : failures) {
    fmt::print(stderr, "fnmpc merge: FAILED {}: vehicle {}: {}\n", f.value("run", std::string()),
               f.value("vehicle", std::string()), f.value("reason", std::string()));
  }
  return failures.empty() ? kExitOk : kExitRunFailed;
}

void Register(CLI::App& app, std::vector<Command>& registry) {
  auto a = std::make_shared<MergeArgs>();
  CLI::App* sub = app.add_subcommand(
      "merge", "Join the shard folders of `fnmpc run --shard I/N` into one run folder");
  sub->add_option("shards", a->shards, "the N shard folders, in any order")
      ->required()
      ->check(CLI::ExistingDirectory);
  sub->add_option("-o,--out", a->out,
                  "the merged run folder (new or empty; never one of the shards nor inside one)")
      ->required();
  sub->add_flag("--overwrite", a->overwrite,
                "replace an earlier merge in -o (only a folder fnmpc wrote that holds nothing "
                "else; replaced once the new merge is complete)");
  registry.push_back({sub, [a] { return Merge(*a); }});
}
const RegisterCommand kRegistered(&Register);

}  // namespace
}  // namespace fnmpc::app
