// strut bench discover: a full discovery run on the 14-experiment standard matrix
// (study::RunDiscoverTiming), with one and two threads side by side.
#include <fmt/format.h>

#include <iostream>
#include <nlohmann/json.hpp>

#include "commands.h"
#include "option_checks.h"
#include "output_files.h"
#include "strut/study/discover_timing.h"

namespace strut::tools {
namespace {

struct BenchDiscover {
  std::string json_path;
  int repeats = 3;

  void Run() const {
    CheckOutputPath("--json", json_path, {});
    std::cout << "discover on the 14-experiment standard matrix from the simulated rig (every effect on), "
                 "stroke input, the default grid:\n";
    const study::DiscoverTimingStudy s = study::RunDiscoverTiming(repeats);
    nlohmann::json rows = nlohmann::json::array();
    for (const study::DiscoverTiming& t : s.settings) {
      std::string missing;
      for (const auto& term : t.missing) missing += " " + term;
      std::cout << fmt::format("  {} thread{}: median wall {:.2f} s, CPU {:.2f} s ({:.2f} cores busy) of {} runs; found{}\n",
                               t.threads, t.threads > 1 ? "s" : "", t.median_wall, t.median_cpu,
                               t.median_cpu / t.median_wall, repeats, missing);
      rows.push_back({{"threads", t.threads}, {"median_seconds", t.median_wall}, {"median_cpu_seconds", t.median_cpu},
                      {"wall_seconds", t.wall}, {"cpu_seconds", t.cpu}, {"missing", t.missing}});
    }
    const study::DiscoverTiming &one = s.settings[0], &two = s.settings[1];
    const double speedup = one.median_wall / two.median_wall;
    std::cout << fmt::format("  two threads against one: {:.2f}x faster (wall); CPU {:.2f}x; target < 10 s wall on two "
                             "cores: {}\n",
                             speedup, two.median_cpu / one.median_cpu, two.median_wall < 10.0 ? "met" : "missed");
    std::cout << fmt::format("  load average (1 min) {:.2f} before, {:.2f} after: figures on a shared machine are only "
                             "comparable side by side\n",
                             s.load_before, s.load_after);
    if (!json_path.empty())
      WriteJsonOutput(json_path,
                      nlohmann::json{{"discover", rows}, {"speedup", speedup}, {"load", {s.load_before, s.load_after}}});
  }
};

}  // namespace

void RegisterBenchDiscover(CLI::App& bench) {
  auto [sub, command] = AddCommand<BenchDiscover>(
      bench, "discover", "Time model discovery: a full run on the standard matrix, with 1 and 2 threads.");
  sub->add_option("--json", command->json_path, "Also write the figures as JSON to this file.");
  sub->add_option("--repeats", command->repeats, "Runs per setting.")->check(Between(1, 20))->capture_default_str();
}

}  // namespace strut::tools
