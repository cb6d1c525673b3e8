// strut bench discover: a full discovery run on the 14-experiment standard matrix.
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
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

struct BenchDiscover {
  std::string json_path;
  int repeats = 3;

  void Run() const {
    // The simulated rig with every effect on: the hardest case, every round refits all candidates.
    const sim::SimulatedRig rig(sim::DefaultTruth());
    const daq::Session session = rig.RunMatrix(sim::StandardMatrixPlan());
    ident::SessionFitOptions fit;
    fit.composition = "1dof";
    const ident::FitData data =
        ident::PrepareFitData(session, "simulated session", ident::Model::Build("1dof", fit.causality), fit.estimator.n);
    nlohmann::json rows = nlohmann::json::array();
    std::cout << "discover on the 14-experiment standard matrix from the simulated rig (every effect on), "
                 "stroke input, n = 800:\n";
    for (const int threads : {1, 2}) {
      ident::DiscoverOptions options;
      options.threads = threads;
      std::vector<double> seconds;
      ident::DiscoveryResult result;
      for (int r = 0; r < repeats; ++r) {
        const auto start = std::chrono::steady_clock::now();
        result = ident::Discover(data, fit, options);
        seconds.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
      }
      std::sort(seconds.begin(), seconds.end());
      const double median = seconds[seconds.size() / 2];
      std::string missing;
      for (const auto& t : result.missing) missing += " " + t;
      std::cout << fmt::format("  {} thread{}: median {:.2f} s of {} runs (target < 20 s on two cores); found{}\n",
                               threads, threads > 1 ? "s" : "", median, repeats, missing);
      rows.push_back({{"threads", threads}, {"median_seconds", median}, {"missing", result.missing}});
    }
    if (!json_path.empty()) std::ofstream(json_path) << nlohmann::json{{"discover", rows}}.dump(1) << "\n";
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
