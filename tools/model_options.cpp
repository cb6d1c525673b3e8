#include "model_options.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>

#include "option_checks.h"

namespace strut::tools {
namespace {

// A base builds alone; a term needs a base (Model::Build refuses it).
bool IsBase(const std::string& name) {
  try {
    ident::Model::Build(name, ident::Causality::kStrokeInput);
    return true;
  } catch (const std::exception&) {
    return false;
  }
}

// The --model help lists the bases and terms of the catalogue itself, so it cannot fall behind.
std::string ModelHelp() {
  std::vector<std::string> bases, terms;
  for (const std::string& name : ident::Model::Catalogue()) (IsBase(name) ? bases : terms).push_back(name);
  return fmt::format(
      "The model: BASE[+TERM...], where BASE is one of {} and each TERM one of {} (docs/models.md). A composition "
      "that equals a base is that base: 1dof+heat-exchange+gas-solubility is 2dof.",
      fmt::join(bases, ", "), fmt::join(terms, ", "));
}

}  // namespace

void ModelOptions::Add(CLI::App& command) {
  command.add_option("--model", composition, ModelHelp())->capture_default_str();
  command.add_option("--input", input,
                     "Causality: stroke (the measured stroke drives the model; force and pressure are outputs) or "
                     "force (the paper's choice; stroke and pressure are outputs).")
      ->check(CLI::IsMember({"force", "stroke"}))
      ->capture_default_str();
  command.add_option("--set", assignments,
                     "Parameter values NAME=VALUE[,NAME=VALUE...], NAME by index or name (theta4 or gas_area); they "
                     "apply after --params. A value outside the parameter's physical range is refused.");
  command.add_option("--params", params_file, "Read parameter values from this file (docs/parameters.md).")
      ->check(CLI::ExistingFile);
}

ident::Model ModelOptions::BuildModel() const {
  return ident::Model::Build(composition, ident::ParseCausality(input));
}

ident::ParameterSet ModelOptions::Parameters(const ident::Model& model) const {
  ident::ParameterSet parameters = model.defaults();
  if (!params_file.empty()) parameters.apply_file(params_file);
  if (!assignments.empty()) parameters.apply_assignments(assignments);
  return parameters;
}

void ModelOptions::AddSessionFit(CLI::App& command) {
  command
      .add_option("--exclude", exclude,
                  "Leave out an experiment (LABEL) or one of its channels (LABEL:CHANNEL); repeat or separate by commas.")
      ->delimiter(',');
  command.add_option("--calibration", calibration,
                     "Relative sd of the transducers' gains, carried into every interval: CHANNEL=SD,... (force=0.1%; the "
                     "channels named are all that is covered) or 'none' (default: force=0.2%,pressure=0.2%,stroke=0.1%; "
                     "docs/identification.md).");
}

ident::SessionFitOptions ModelOptions::FitOptions(int n) const {
  ident::SessionFitOptions options;
  options.composition = composition;
  options.causality = ident::ParseCausality(input);
  options.params_file = params_file;
  options.assignments = assignments;
  options.exclude = exclude;
  options.estimator.n = n;
  if (!calibration.empty()) {
    try {
      options.estimator.gain_sd = ident::ParseGainSd(calibration);
      ident::CheckGainChannels(options.estimator.gain_sd, ident::Model::Build(composition, options.causality));
    } catch (const ident::ModelError&) {
      throw;  // a bad --model, named by its own option
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument(std::string("--calibration: ") + e.what());
    }
  }
  return options;
}

void AddFitGridOption(CLI::App& command, int& n) {
  command
      .add_option("--n", n,
                  "Grid points per period of the periodic solver, at least: the grid is equidistant and holds every "
                  "recorded sample phase. Default: under stroke input the sample phases, thinned where the model is "
                  "smooth (200 a period there); under force input 800 (docs/identification.md).")
      ->check(Between(16, 100000));
}

}  // namespace strut::tools
