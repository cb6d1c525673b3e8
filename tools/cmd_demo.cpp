// strut demo: the main job on the simulated rig, on a unit nobody has characterised. Draws a
// damper with realistic scatter (sim::DrawUnit, a fixed documented seed, so the demo is
// reproducible) that holds 2 dof physics and two catalogue effects, runs the standard test matrix
// on it, records the session, identifies the paper's 1 dof and 2 dof models, lets discovery name
// what 1 dof leaves out, and holds everything found against the truth it simulated.
// Progress goes to the log (stderr), one line per step; results to stdout.
#include <fmt/format.h>
#include <fmt/ranges.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <iostream>

#include "commands.h"
#include "option_checks.h"
#include "output_files.h"
#include "strut/daq/session.h"
#include "strut/ident/discover.h"
#include "strut/ident/estimator.h"
#include "strut/report/discover_report.h"
#include "strut/report/fit_report.h"
#include "strut/rig/safety.h"
#include "strut/rig/test_matrix.h"
#include "strut/ident/session_fit.h"
#include "strut/sim/draw.h"
#include "strut/sim/simulated_rig.h"
#include "strut/sim/truth.h"

namespace strut::tools {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

//! The unit the demo draws unless --unit says otherwise (docs/demo.md): a 2dof damper with
//! oil compressibility and Stribeck friction, its parameters scattered around the shipped truth.
constexpr std::uint64_t kDemoUnitSeed = 12;
//! The unit of the demo's last step: a 2dof damper with a dead volume on its pressure line, which
//! pressure-dependent heat transfer explains alike on the standard matrix (docs/discovery.md).
constexpr std::uint64_t kAlikeUnitSeed = 2022;
constexpr int kSteps = 7;

double Seconds(Clock::time_point since) { return std::chrono::duration<double>(Clock::now() - since).count(); }

void Step(int step, const std::string& what) { spdlog::info("demo step {} of {}: {}", step, kSteps, what); }

std::string List(const std::vector<std::string>& names) {
  return names.empty() ? std::string("none") : fmt::format("{}", fmt::join(names, ", "));
}

// The fitted parameters against the truth the rig simulated: estimate ± sd, truth, and
// z = (estimate - truth) / sd. Parameters the truth does not hold (same key, another meaning in
// the other model) show "-".
std::string TruthTable(const ident::FitSummary& fit, const ident::ParameterSet& truth) {
  std::string text = fmt::format("     {:<8} {:<28} {:>12}   {:<9} {:<9} {:>12} {:>7}\n", "", "parameter", "estimate",
                                 "± sd", "unit", "truth", "z");
  for (int i : fit.estimated_positions) {
    const auto& spec = fit.parameters.spec(i);
    const auto t = truth.find(spec.key());
    const bool comparable = t && truth.spec(*t).name == spec.name;
    const double z = comparable ? (fit.parameters.value(i) - truth.value(*t)) / fit.estimates[i].sd : NAN;
    text += fmt::format("     {:<8} {:<28} {:>12.6g} ± {:<9.2g} {:<9} {:>12} {:>7}\n", spec.key(), spec.name,
                        fit.parameters.value(i), fit.estimates[i].sd, spec.unit,
                        comparable ? fmt::format("{:.6g}", truth.value(*t)) : std::string("-"),
                        std::isfinite(z) ? fmt::format("{:+.1f}", z) : std::string("-"));
  }
  return text;
}

std::string ChannelLines(const ident::FitSummary& fit) {
  std::string text;
  for (const auto& c : fit.channels)
    text += fmt::format("     {:<9} residual rms {:9.4g}, residual over noise variance {:.2f} (1 at the noise floor)\n",
                        c.name, c.rms, c.noise_ratio);
  return text;
}

struct DemoCommand {
  std::string out_dir = "strut-demo";
  bool out_given = false;
  bool force = false;
  std::uint64_t unit = kDemoUnitSeed;
  unsigned long seed = 1;
  int threads = 2;

  // The folder this run writes to. Without --out a fresh one (strut-demo, strut-demo-2, ...), so a
  // run never replaces an earlier one; an --out folder that already holds files is refused
  // unless --force, as every command refuses to replace a session.
  std::string OutputFolder() const {
    std::error_code ec;
    if (!out_given) {
      for (int k = 1;; ++k) {
        const std::string candidate = k == 1 ? out_dir : fmt::format("{}-{}", out_dir, k);
        if (!fs::exists(candidate, ec)) return candidate;
      }
    }
    if (fs::exists(out_dir, ec) && !fs::is_directory(out_dir, ec))
      throw std::invalid_argument(fmt::format("--out {}: exists and is not a folder", out_dir));
    if (fs::is_directory(out_dir, ec) && !fs::is_empty(out_dir, ec) && !force)
      throw std::invalid_argument(fmt::format(
          "--out {}: the folder is not empty (an earlier demo?); choose another folder, leave --out away for a fresh "
          "one, or add --force to replace its files",
          out_dir));
    return out_dir;
  }

  void WriteFit(const ident::FitSummary& fit, const std::string& stem, const std::string& title) const {
    WriteJsonOutput(stem + ".json", report::FitToJson(fit));
    report::WriteFitReport(fit, stem + ".html", title);
    spdlog::info("wrote {}.html", stem);
  }

  void Run() const {
    const std::string folder = OutputFolder();
    fs::create_directories(folder);
    const std::string session_path = folder + "/session.h5";
    CheckOutputPath("--out", session_path, {}, force);

    // 1. A unit nobody has characterised: 2 dof physics plus two catalogue effects, every
    // parameter scattered around the shipped truth (docs/simulated-rig.md, Drawn units).
    Step(1, fmt::format("drawing unit {} (2dof + oil-compressibility + stribeck-friction)", unit));
    sim::UnitDraw draw;
    draw.base = "2dof";
    draw.effects = {{"oil-compressibility", std::nullopt}, {"stribeck-friction", std::nullopt}};
    const sim::SimulatedRig rig(sim::DrawUnit(draw, unit));
    const ident::ParameterSet truth = rig.truth().RecordedParameters(rig.model());
    std::cout << fmt::format("1. drawn unit {} (--unit): {}, parameters scattered around the shipped truth\n", unit,
                             rig.truth().Composition());
    for (const sim::EffectSize& e : rig.truth().drawn->effects)
      std::cout << fmt::format("   {:<20} {} = {:.4g} ({})\n", e.effect, e.parameter, e.size,
                               e.given ? "given" : "drawn");

    // 2. The rig: the standard matrix, recorded as a session.
    Step(2, "the standard matrix on the simulated rig (a few seconds)");
    sim::RigRunOptions run;
    run.seed = seed;
    auto start = Clock::now();
    daq::WriteSession(session_path, rig.RunMatrix(rig::StandardMatrixPlan(), run));
    std::cout << fmt::format(
        "\n2. simulated rig: the 14 experiments of the standard matrix recorded to {} ({:.1f} s)\n", session_path,
        Seconds(start));

    // 3, 4. Identification: the paper's 1 dof and 2 dof models, starting values from the data.
    const daq::Session session = daq::ReadSession(session_path);
    std::vector<ident::FitSummary> fits;
    for (const char* composition : {"1dof", "2dof"}) {
      const int step = static_cast<int>(fits.size()) + 3;
      Step(step, fmt::format("identifying the {} model (every parameter the data determine)", composition));
      ident::SessionFitOptions options;
      options.composition = composition;
      const ident::Model model = ident::Model::Build(composition, options.causality);
      start = Clock::now();
      ident::FitSummary fit =
          ident::FitPrepared(ident::PrepareFitData(session, session_path, model, options.estimator.n), model, options)
              .summary;
      std::cout << fmt::format(
          "\n{}. identification of {} (stroke input): {:.1f} s, {} iterations, BIC {:.6g}\n   {}\n", step, composition,
          Seconds(start), fit.iterations, fit.bic, fit.VerdictText());
      std::cout << TruthTable(fit, truth) << ChannelLines(fit);
      for (const auto& w : fit.warnings) std::cout << "     warning: " << w << "\n";
      WriteFit(fit, folder + "/fit-" + composition,
               std::string("strut demo: ") + composition + " on drawn unit " + std::to_string(unit));
      fits.push_back(std::move(fit));
    }
    std::cout << fmt::format("   ΔBIC (2dof - 1dof) = {:+.1f}: the 2 dof model explains the data {}.\n",
                             fits[1].bic - fits[0].bic, fits[1].bic < fits[0].bic ? "better" : "no better");

    // 5. Discovery from 1 dof: what physics do the recordings show beyond it?
    Step(5, "discovery from 1dof (up to a minute: every round refits every candidate)");
    start = Clock::now();
    ident::SessionFitOptions baseline;
    baseline.composition = "1dof";
    const ident::Model baseline_model = ident::Model::Build("1dof", baseline.causality);
    ident::DiscoverOptions discover;
    discover.threads = threads;
    const ident::DiscoveryResult found = ident::Discover(
        ident::PrepareFitData(session, session_path, baseline_model, baseline.estimator.n), baseline, discover);
    std::cout << fmt::format("\n5. discovery from 1dof ({:.1f} s):\n", Seconds(start));
    for (const auto& s : found.steps)
      std::cout << fmt::format("   + {:<20} ΔBIC {:+11.1f}   {}\n", s.term, s.delta_bic, s.evidence);
    std::cout << "   " << found.conclusion << "\n";
    WriteFit(found.final_fit, folder + "/fit-discovered",
             "strut demo: " + found.final_model + " found by discovery on drawn unit " + std::to_string(unit));

    // 6. Against the truth the rig simulated: the terms the unit holds beyond the baseline, and
    // what discovery named of them, missed, or added that is not there.
    Step(6, "comparing with the truth the rig simulated");
    std::vector<std::string> expected, named, missed, extra;
    const auto in = [](const std::vector<std::string>& list, const std::string& name) {
      return std::find(list.begin(), list.end(), name) != list.end();
    };
    for (const std::string& effect : rig.truth().effects)
      if (!baseline_model.has_term(effect)) expected.push_back(effect);
    for (const std::string& effect : expected) (in(found.missing, effect) ? named : missed).push_back(effect);
    for (const std::string& term : found.missing)
      if (!in(expected, term)) extra.push_back(term);
    std::cout << fmt::format(
        "\n6. against the truth ({}; beyond 1dof it holds {}):\n   found {}; missed {}; extra {}\n",
        rig.truth().Composition(), List(expected), List(named), List(missed), List(extra));
    std::cout << fmt::format(
        "   the discovered model {} {} the truth's composition; its parameters against the truth "
        "(z = (estimate - truth) / sd):\n",
        found.final_model, found.final_model == rig.model().composition() ? "is" : "is not");
    std::cout << TruthTable(found.final_fit, truth);
    Alike(folder);
    std::cout << fmt::format("\n   Written to {0}/: session.h5, fit-1dof, fit-2dof and fit-discovered (.json, .html), "
                             "alike.h5, discover-alike.json, decide-matrix.toml and decide.h5\n",
                             folder);
  }

  // 7. Two explanations that fit alike: discovery says so, proposes the test that decides, the
  // simulated rig runs it, and the data with it choose.
  void Alike(const std::string& folder) const {
    Step(7, fmt::format("unit {} (2dof + dead-volume): two explanations that fit alike, and the test that decides",
                        kAlikeUnitSeed));
    sim::UnitDraw draw;
    draw.effects = {{"dead-volume", std::nullopt}};
    sim::Truth truth = sim::DrawUnit(draw, kAlikeUnitSeed);
    truth.actuator.ideal = true;
    const sim::SimulatedRig rig(truth);
    sim::RigRunOptions run;
    run.seed = seed;
    const std::string session_path = folder + "/alike.h5";
    daq::WriteSession(session_path, rig.RunMatrix(rig::StandardMatrixPlan(), run));
    const auto start = Clock::now();
    ident::SessionFitOptions fit;
    const ident::Model model = ident::Model::Build(fit.composition, fit.causality);
    const ident::FitData data = ident::ReadFitData({session_path}, model, fit.estimator.n);
    ident::DiscoverOptions discover;
    discover.threads = threads;
    discover.test_space = rig::DecisiveTestSpace(data.experiments, rig::SafetyConfig{});
    ident::DiscoveryResult found = ident::Discover(data, fit, discover);
    std::cout << fmt::format("\n7. drawn unit {} ({}), discovery from 2dof ({:.1f} s):\n   {}\n", kAlikeUnitSeed,
                             rig.truth().Composition(), Seconds(start), found.conclusion);
    const ident::Ambiguity* ambiguity = ident::DecidableAmbiguity(found);
    if (!ambiguity) {
      std::cout << "   nothing was ambiguous on this unit: there is no test to run.\n";
      WriteJsonOutput(folder + "/discover-alike.json", report::DiscoveryJson(found));
      return;
    }
    const ident::DecisiveTest& test = *ambiguity->test;
    const rig::MatrixPlan plan = rig::DecisiveTestPlan(test);
    WriteTextOutput(folder + "/decide-matrix.toml",
                    rig::MatrixFileText(plan, "strut demo: the test that decides\n" + test.Describe()));
    const std::string decide_path = folder + "/decide.h5";
    daq::WriteSession(decide_path, rig.RunMatrix(plan, run));
    found.decision = ident::DecideAmbiguity(found, ident::ReadFitData({session_path, decide_path}, model, fit.estimator.n),
                                            fit, discover);
    WriteJsonOutput(folder + "/discover-alike.json", report::DiscoveryJson(found));
    const ident::Decision& d = *found.decision;
    const std::string decided = d.winner >= 0 ? d.models[d.winner] : "";
    std::cout << fmt::format("   the test ran on the simulated rig ({:.1f} min of rig time, recorded to {}):\n   {}\n"
                             "   the truth is {}: {}.\n",
                             test.minutes, decide_path, found.decision->conclusion, rig.truth().Composition(),
                             decided.empty()                               ? "the data did not decide"
                             : decided == rig.model().composition() ? "decided right"
                                                                           : "decided WRONG");
  }
};

}  // namespace

void RegisterDemoCommand(CLI::App& app) {
  auto [sub, command] = AddCommand<DemoCommand>(
      app, "demo",
      "Run the main job on the simulated rig: draw a unit (2 dof physics plus oil compressibility and Stribeck "
      "friction), record the standard matrix, identify the 1 dof and 2 dof models, discover what 1 dof leaves out, "
      "and compare everything with the drawn truth (docs/demo.md).");
  CLI::Option* out = sub->add_option("--out", command->out_dir,
                                     "Write the session, fits and reports into this folder. Without it a fresh folder "
                                     "is chosen (strut-demo, strut-demo-2, ...), so no run replaces another.");
  sub->add_flag("--force", command->force, "Replace the files in an --out folder that is not empty.");
  sub->add_option("--unit", command->unit,
                  "The seed of the drawn unit: the same seed gives the same damper (docs/simulated-rig.md).")
      ->capture_default_str();
  sub->add_option("--seed", command->seed, "The seed of the rig's noise: the same seed gives the same session.")
      ->capture_default_str();
  sub->add_option("--threads", command->threads, "Threads of discovery: candidate refits, cross-validation folds and the experiments of each fit side by side.")
      ->check(Between(1, 64))
      ->capture_default_str();
  // Replaces AddCommand's callback: Run needs to know whether --out was given, not only its value.
  sub->callback([command = command, out] {
    command->out_given = out->count() > 0;
    command->Run();
  });
}

}  // namespace strut::tools
