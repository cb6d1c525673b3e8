// strut bench discover: a full discovery run on the 14-experiment standard matrix.
#include <spdlog/spdlog.h>

#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>

#include "commands.h"
#include "option_checks.h"
#include "strut/ident/discover.h"
#include "strut/sim/simulated_rig.h"
#include "strut/sim/truth.h"

namespace strut::tools {
namespace {

//! CPU time of the process so far (every thread), user and system.
double ProcessCpuSeconds() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_utime.tv_sec + usage.ru_stime.tv_sec + 1e-6 * (usage.ru_utime.tv_usec + usage.ru_stime.tv_usec);
}

double LoadAverage() {
  double load[1] = {NAN};
  return getloadavg(load, 1) == 1 ? load[0] : NAN;
}

double Median(std::vector<double> values) {
  std::sort(values.begin(), values.end());
  return values[values.size() / 2];
}

struct BenchDiscover {
  std::string json_path;
  int repeats = 3;

  void Run() const {
    // The simulated rig with every effect on: the hardest case, every round refits all candidates.
    const sim::SimulatedRig rig(sim::DefaultTruth());
    const daq::Session session = rig.RunMatrix(rig::StandardMatrixPlan());
    ident::SessionFitOptions fit;
    fit.composition = "1dof";
    const ident::FitData data =
        ident::PrepareFitData(session, "simulated session", ident::Model::Build("1dof", fit.causality), fit.estimator.n);
    nlohmann::json rows = nlohmann::json::array();
    std::cout << "discover on the 14-experiment standard matrix from the simulated rig (every effect on), "
                 "stroke input, the default grid:\n";
    // The thread counts alternate within each repeat, so a change in the machine's load falls on both.
    const std::vector<int> counts{1, 2};
    std::vector<std::vector<double>> wall(counts.size()), cpu(counts.size());
    std::vector<ident::DiscoveryResult> results(counts.size());
    const double load_before = LoadAverage();
    for (int r = 0; r < repeats; ++r)
      for (std::size_t k = 0; k < counts.size(); ++k) {
        ident::DiscoverOptions options;
        options.threads = counts[k];
        const double cpu_start = ProcessCpuSeconds();
        const auto start = std::chrono::steady_clock::now();
        results[k] = ident::Discover(data, fit, options);
        wall[k].push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
        cpu[k].push_back(ProcessCpuSeconds() - cpu_start);
      }
    const double load_after = LoadAverage();
    for (std::size_t k = 0; k < counts.size(); ++k) {
      std::string missing;
      for (const auto& t : results[k].missing) missing += " " + t;
      const double w = Median(wall[k]), c = Median(cpu[k]);
      std::cout << fmt::format("  {} thread{}: median wall {:.2f} s, CPU {:.2f} s ({:.2f} cores busy) of {} runs; found{}\n",
                               counts[k], counts[k] > 1 ? "s" : "", w, c, c / w, repeats, missing);
      rows.push_back({{"threads", counts[k]}, {"median_seconds", w}, {"median_cpu_seconds", c}, {"wall_seconds", wall[k]},
                      {"cpu_seconds", cpu[k]}, {"missing", results[k].missing}});
    }
    const double speedup = Median(wall[0]) / Median(wall[1]);
    std::cout << fmt::format("  two threads against one: {:.2f}x faster (wall); CPU {:.2f}x; target < 20 s wall on two "
                             "cores: {}\n",
                             speedup, Median(cpu[1]) / Median(cpu[0]), Median(wall[1]) < 20.0 ? "met" : "missed");
    std::cout << fmt::format("  load average (1 min) {:.2f} before, {:.2f} after: figures on a shared machine are only "
                             "comparable side by side\n",
                             load_before, load_after);
    if (!json_path.empty())
      std::ofstream(json_path) << nlohmann::json{{"discover", rows}, {"speedup", speedup}, {"load", {load_before, load_after}}}
                                      .dump(1)
                               << "\n";
  }
};

}  // namespace

void RegisterBenchDiscover(CLI::App& bench) {
  auto command = std::make_shared<BenchDiscover>();
  CLI::App* sub = bench.add_subcommand("discover", "Time model discovery: a full run on the standard matrix, with 1 and 2 threads.");
  sub->add_option("--json", command->json_path, "Also write the figures as JSON to this file.");
  sub->add_option("--repeats", command->repeats, "Runs per setting.")->check(Between(1, 20))->capture_default_str();
  sub->callback([command] { command->Run(); });
}

}  // namespace strut::tools
