// strut demo: the main job on the simulated rig. Runs the standard test matrix on the simulated
// rig (actuator, sensors, a damper with every extra effect of the default truth), records the
// session, identifies the paper's 1 dof and 2 dof models, lets discovery name what they leave
// out, and writes the fits (JSON) and reports (HTML).
#include <fmt/ranges.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <iostream>

#include "commands.h"
#include "strut/daq/session.h"
#include "strut/ident/estimator.h"
#include "strut/ident/fit_report.h"
#include "strut/ident/session_fit.h"
#include "strut/rig/test_matrix.h"
#include "strut/ident/discover.h"
#include "strut/sim/simulated_rig.h"
#include "strut/sim/truth.h"

namespace strut::tools {
namespace {

struct DemoCommand {
  std::string out_dir = "strut-demo";
  unsigned seed = 1;

  void Run() const {
    using Clock = std::chrono::steady_clock;
    std::filesystem::create_directories(out_dir);
    const std::string session_path = out_dir + "/session.h5";

    // 1. The rig: the standard matrix on the simulated rig, default truth (every effect on).
    // Progress goes to the log (stderr) as each step starts; results to stdout.
    spdlog::info("demo step 1 of 3: the standard matrix on the simulated rig (a few seconds)");
    const sim::SimulatedRig rig(sim::DefaultTruth());
    sim::RigRunOptions run;
    run.seed = seed;
    auto start = Clock::now();
    daq::WriteSession(session_path, rig.RunMatrix(sim::StandardMatrixPlan(), run));
    const ident::ParameterSet truth = rig.truth().Parameters(rig.model());
    std::cout << fmt::format("1. simulated rig ({}): 14 experiments of the standard matrix recorded to {} ({:.1f} s)\n",
                             rig.truth().Composition(), session_path,
                             std::chrono::duration<double>(Clock::now() - start).count());

    // 2. Identification: the paper's 1 dof and 2 dof models, starting values from the data.
    const daq::Session session = daq::ReadSession(session_path);
    std::cout << "2. identification (stroke input; every parameter the data determine):\n";
    std::vector<ident::FitSummary> fits;
    for (const char* composition : {"1dof", "2dof"}) {
      spdlog::info("demo step 2 of 3: identifying the {} model (every parameter the data determine)", composition);
      ident::SessionFitOptions options;
      options.composition = composition;
      const ident::Model model = ident::Model::Build(composition, options.causality);
      start = Clock::now();
      ident::FitSummary fit =
          ident::FitPrepared(ident::PrepareFitData(session, session_path, model, options.estimator.n), model, options)
              .summary;
      const double seconds = std::chrono::duration<double>(Clock::now() - start).count();
      std::cout << fmt::format("\n   {} fitted in {:.2f} s, {} iterations, BIC {:.6g}\n   {}\n", composition, seconds,
                               fit.iterations, fit.bic, fit.VerdictText());
      for (int i : fit.estimated_positions) {
        const auto& spec = fit.parameters.spec(i);
        const auto t = truth.find(spec.key());
        const bool comparable = t && truth.spec(*t).name == spec.name;
        std::cout << fmt::format("     {:<8} {:<26} {:>12.6g} ± {:<9.2g} {:<6} truth {}\n", spec.key(), spec.name,
                                 fit.parameters.value(i), fit.sd[i], spec.unit,
                                 comparable ? fmt::format("{:.6g}", truth.value(*t)) : std::string("-"));
      }
      for (const auto& c : fit.channels)
        std::cout << fmt::format("     {:<9} residual rms {:9.4g}, {:6.1f} x the noise floor\n", c.name, c.rms,
                                 c.noise_ratio);
      for (const auto& w : fit.warnings) std::cout << "     warning: " << w << "\n";
      const std::string stem = out_dir + "/fit-" + composition;
      std::ofstream(stem + ".json") << ident::FitToJson(fit).dump(1) << "\n";
      ident::WriteFitReport(fit, stem + ".html", std::string("strut demo: ") + composition + " on the simulated rig");
      fits.push_back(std::move(fit));
    }
    std::cout << fmt::format("\n   the 2 dof model explains the data {} (BIC {:.6g} against {:.6g} for 1 dof).\n",
                             fits[1].bic < fits[0].bic ? "better" : "no better", fits[1].bic, fits[0].bic);

    // 3. Discovery from 1 dof: what physics do the recordings show beyond it?
    spdlog::info("demo step 3 of 3: discovery from 1dof (up to a minute: every round refits every candidate)");
    std::cout << "\n3. discovery from 1dof (the truth has every effect of the catalogue):\n";
    start = Clock::now();
    ident::SessionFitOptions baseline;
    baseline.composition = "1dof";
    const ident::DiscoveryResult found = ident::Discover(
        ident::PrepareFitData(session, session_path, ident::Model::Build("1dof", baseline.causality), baseline.estimator.n),
        baseline, {});
    for (const auto& step : found.steps)
      std::cout << fmt::format("   + {:<20} ΔBIC {:+11.1f}   {}\n", step.term, step.delta_bic, step.evidence);
    std::cout << fmt::format("   {} ({:.1f} s)\n", found.conclusion,
                             std::chrono::duration<double>(Clock::now() - start).count());
    // Against the truth the rig simulated: what discovery named, missed, or added that is not there.
    std::vector<std::string> named, missed, extra;
    const auto in = [](const std::vector<std::string>& list, const std::string& name) {
      return std::find(list.begin(), list.end(), name) != list.end();
    };
    for (const std::string& effect : rig.truth().effects) (in(found.missing, effect) ? named : missed).push_back(effect);
    for (const std::string& term : found.missing)
      if (!in(rig.truth().effects, term)) extra.push_back(term);
    const auto list = [](const std::vector<std::string>& v) { return v.empty() ? std::string("none") : fmt::format("{}", fmt::join(v, ", ")); };
    std::cout << fmt::format("   against the simulated truth: found {}; missed {}; extra {}\n", list(named), list(missed),
                             list(extra));
    std::cout << fmt::format("\n   Fits: {0}/fit-*.json, reports: {0}/fit-*.html, session: {1}\n", out_dir, session_path);
  }
};

}  // namespace

void RegisterDemoCommand(CLI::App& app) {
  auto command = std::make_shared<DemoCommand>();
  CLI::App* sub = app.add_subcommand("demo", "Run the main job on the simulated rig: record the standard matrix, identify");
  sub->add_option("--out", command->out_dir, "Directory for the session, fits and reports")->capture_default_str();
  sub->add_option("--seed", command->seed, "Noise seed of the simulated rig")->capture_default_str();
  sub->callback([command] { command->Run(); });
}

}  // namespace strut::tools
