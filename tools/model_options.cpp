#include "model_options.h"

namespace strut::tools {

void ModelOptions::Add(CLI::App& command) {
  command.add_option("--model", composition, "Model: BASE[+term...], BASE 1dof or 2dof (e.g. 1dof+heat-exchange)")
      ->capture_default_str();
  command.add_option("--input", input,
                     "Causality: stroke (the measured stroke drives the model; force and pressure are outputs) or "
                     "force (the paper's choice; stroke and pressure are outputs).")
      ->check(CLI::IsMember({"force", "stroke"}))
      ->capture_default_str();
  command.add_option("--set", assignments, "Parameter values: NAME=VALUE[,NAME=VALUE...] (NAME: theta4 or gas_area)");
  command.add_option("--params", params_file, "Parameter file (docs/parameters.md)")->check(CLI::ExistingFile);
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

void ModelOptions::AddExclude(CLI::App& command) {
  command
      .add_option("--exclude", exclude,
                  "Leave out an experiment (LABEL) or one of its channels (LABEL:CHANNEL); repeat or separate by commas.")
      ->delimiter(',');
}

ident::SessionFitOptions ModelOptions::FitOptions(int n) const {
  ident::SessionFitOptions options;
  options.composition = composition;
  options.causality = ident::ParseCausality(input);
  options.params_file = params_file;
  options.assignments = assignments;
  options.exclude = exclude;
  options.estimator.n = n;
  return options;
}

}  // namespace strut::tools
