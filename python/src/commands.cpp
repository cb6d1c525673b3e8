// identify, discover, qc, predict_drop, sim_matrix and sim_drop from Python. Keyword arguments are
// turned into the command's own command line and parsed by the CLI's option definitions
// (tools/*_command.h), so names, defaults, ranges and messages are the CLI's; the work is the same
// call the CLI makes (IdentifyCommand::Fit, ...), only the printing is left out.
#include <fmt/format.h>
#include <fmt/ranges.h>
#include <pybind11/eigen.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <cmath>
#include <memory>

#include "bindings.h"
#include "discover_command.h"
#include "identify_command.h"
#include "predict_command.h"
#include "qc_commands.h"
#include "sim_commands.h"
#include "strut/ident/discover.h"
#include "strut/report/discover_report.h"
#include "strut/report/fit_report.h"
#include "strut/report/qc_report.h"

namespace strut::python {
namespace {

//! "--estimate-input" for the keyword estimate_input.
std::string OptionName(const std::string& keyword) {
  std::string name = "--" + keyword;
  std::replace(name.begin(), name.end(), '_', '-');
  return name;
}

//! The keywords a command takes: its long options with '-' as '_', and the options.
std::vector<std::pair<std::string, const CLI::Option*>> Keywords(const CLI::App& app) {
  std::vector<std::pair<std::string, const CLI::Option*>> keywords;
  for (const CLI::Option* o : app.get_options()) {
    if (o->get_lnames().empty() || o->get_lnames().front() == "help") continue;
    std::string k = o->get_lnames().front();
    std::replace(k.begin(), k.end(), '-', '_');
    keywords.emplace_back(k, o);
  }
  return keywords;
}

//! A word of the command line: a path or text as it is, a number as str() gives it (a float's
//! shortest exact form).
std::string Word(const py::handle& item) {
  const py::module_ os = py::module_::import("os");
  if (py::isinstance<py::str>(item) || py::isinstance(item, os.attr("PathLike"))) return py::str(os.attr("fspath")(item));
  return py::str(item);
}

//! Parses `positional` and `kwargs` as `strut <command> ...` with the options `app` defines: a
//! keyword NAME is the option --NAME ('_' for '-'); a flag takes True or False; a list or tuple
//! repeats the option; None leaves it out (its default). An unknown keyword is a TypeError.
void Parse(CLI::App& app, const std::string& command, const std::vector<std::string>& positional,
           const py::dict& kwargs) {
  std::vector<std::string> words = positional;
  for (const auto& [key, value] : kwargs) {
    const std::string keyword = py::str(key);
    const std::string option = OptionName(keyword);
    const CLI::Option* o = keyword == "help" ? nullptr : app.get_option_no_throw(option);
    if (!o || o->get_lnames().empty()) {
      std::vector<std::string> known;
      for (const auto& [k, unused] : Keywords(app)) known.push_back(k);
      std::string function = command;
      std::replace(function.begin(), function.end(), ' ', '_');
      throw py::type_error(fmt::format("{}() got an unexpected keyword argument '{}': strut {} has no option {} (its "
                                       "keyword arguments: {})",
                                       function, keyword, command, option, fmt::join(known, ", ")));
    }
    if (value.is_none()) continue;
    if (o->get_expected_max() == 0) {  // a flag
      if (!py::isinstance<py::bool_>(value))
        throw py::type_error(fmt::format("{}: {} is the flag {}: give True or False", command, keyword, option));
      if (value.cast<bool>()) words.push_back(option);
      continue;
    }
    const bool many = py::isinstance<py::list>(value) || py::isinstance<py::tuple>(value);
    const py::sequence items = many ? py::reinterpret_borrow<py::sequence>(value) : py::sequence(py::make_tuple(value));
    // --NAME=VALUE, one word: a value such as -1 is never taken for an option.
    for (const py::handle item : items) words.push_back(option + "=" + Word(item));
  }
  std::reverse(words.begin(), words.end());  // CLI11 takes a vector last word first
  try {
    app.parse(words);
  } catch (const CLI::ParseError& e) {
    throw OptionError(e.what());
  }
}

std::vector<std::string> Words(const py::sequence& sequence) {
  std::vector<std::string> words;
  for (const py::handle item : sequence) words.push_back(Word(item));
  return words;
}

//! A command object with its options parsed from Python arguments, and the options it was parsed
//! with (TruthOptions::Load asks them what was given).
template <typename Command>
struct ParsedCommand {
  Command command;
  CLI::App app;
  ParsedCommand(void (*add)(CLI::App&, Command&), const std::string& name, const std::vector<std::string>& positional,
                const py::dict& kwargs)
      : app("strut " + name, "strut " + name) {
    add(app, command);
    Parse(app, name, positional, kwargs);
  }
};

// A fit as the Python layer reads it (strut/results.py): the summary, and the JSON the CLI writes.
struct PyFit {
  std::shared_ptr<const ident::FitSummary> summary;
  std::string json;  //!< the CLI's JSON of the fit (identify --json), as text

  const ident::FitSummary& s() const { return *summary; }
};

PyFit MakeFit(ident::FitSummary summary, const nlohmann::json& json) {
  return PyFit{std::make_shared<const ident::FitSummary>(std::move(summary)), json.dump()};
}

//! Columns of the parameter table, straight from the summary: the JSON's field names.
py::dict ParameterColumns(const ident::FitSummary& s) {
  std::vector<std::string> index, name, unit;
  std::vector<double> value, sd, input_noise, misfit, calibration;
  std::vector<bool> estimated;
  for (int i = 0; i < s.parameters.size(); ++i) {
    const ident::ParameterSpec& spec = s.parameters.spec(i);
    index.push_back(spec.key());
    name.push_back(spec.name);
    unit.push_back(spec.unit);
    value.push_back(s.parameters.value(i));
    sd.push_back(s.estimates[i].sd);
    input_noise.push_back(s.estimates[i].input_noise_sd_factor);
    misfit.push_back(s.estimates[i].misfit_sd_factor);
    calibration.push_back(s.estimates[i].calibration_sd);
    estimated.push_back(s.estimates[i].estimated);
  }
  py::dict d;
  d["index"] = index;
  d["name"] = name;
  d["unit"] = unit;
  d["value"] = Array(value);
  d["sd"] = Array(sd);
  d["sd_input_noise_factor"] = Array(input_noise);
  d["sd_misfit_factor"] = Array(misfit);
  d["sd_calibration"] = Array(calibration);
  d["estimated"] = estimated;
  return d;
}

py::list ChannelRows(const ident::FitSummary& s) {
  py::list rows;
  for (const ident::FitChannel& c : s.channels) {
    py::dict r;
    r["name"] = c.name;
    r["variance"] = c.variance;
    r["noise_floor_variance"] = c.noise_floor_variance;
    r["rms"] = c.rms;
    r["noise_ratio"] = c.noise_ratio;
    r["noise_ratio_sd"] = c.noise_ratio_sd;
    r["noise_floor_limit"] = c.noise_floor_limit;
    r["above_noise_floor"] = c.AboveNoiseFloor();
    rows.append(r);
  }
  return rows;
}

py::dict Vectors(const std::map<std::string, Eigen::VectorXd>& channels) {
  py::dict d;
  for (const auto& [name, v] : channels) d[py::str(name)] = py::array_t<double>(v.size(), v.data());
  return d;
}

//! Per periodic experiment: its figures per channel and the averaged records the report plots.
py::list ExperimentRows(const ident::FitSummary& s) {
  py::list rows;
  for (const ident::ExperimentFit& e : s.experiments) {
    py::dict r;
    r["label"] = e.label;
    r["group"] = e.group;
    r["session"] = e.session;
    r["frequency"] = e.frequency;
    r["amplitude"] = e.amplitude;
    r["static_position"] = e.static_position;
    r["converged"] = e.converged;
    r["error"] = e.error;
    py::dict figures;
    for (const ident::ChannelStatistics& c : e.channels)
      figures[py::str(c.channel)] =
          py::dict(py::arg("mean") = c.mean, py::arg("sd") = c.sd, py::arg("rms") = c.rms,
                   py::arg("noise_ratio") = c.noise_ratio, py::arg("fitted") = c.fitted);
    r["channels"] = figures;
    r["phase"] = Array(e.phases);
    r["measured"] = Vectors(e.measured);
    r["residual"] = Vectors(e.residual);
    r["noise_variance"] = e.noise_variance;
    rows.append(r);
  }
  return rows;
}

py::object ToPythonJson(const nlohmann::json& j) {
  return py::module_::import("json").attr("loads")(j.dump());
}

struct PyDiscovery {
  std::shared_ptr<const ident::DiscoveryResult> result;
};

struct PyQc {
  std::shared_ptr<const tools::QcOutcome> outcome;
};

struct PyDrop {
  std::shared_ptr<const report::DropComparison> drop;
};

}  // namespace

void AddCommands(py::module_& m) {
  py::class_<PyFit>(m, "Fit", "A fit's summary (the pure-Python strut.Fit wraps it).")
      .def_property_readonly("model", [](const PyFit& f) { return f.s().model; })
      .def_property_readonly("converged", [](const PyFit& f) { return f.s().converged; })
      .def_property_readonly("iterations", [](const PyFit& f) { return f.s().iterations; })
      .def_property_readonly("verdict", [](const PyFit& f) { return std::string(ident::ToString(f.s().Verdict())); })
      .def_property_readonly("verdict_text", [](const PyFit& f) { return f.s().VerdictText(); })
      .def_property_readonly("loglik", [](const PyFit& f) { return f.s().loglik; })
      .def_property_readonly("aic", [](const PyFit& f) { return f.s().aic; })
      .def_property_readonly("bic", [](const PyFit& f) { return f.s().bic; })
      .def_property_readonly("observations", [](const PyFit& f) { return f.s().observations; })
      .def_property_readonly("warnings", [](const PyFit& f) { return f.s().warnings; })
      .def_property_readonly("calibration", [](const PyFit& f) { return f.s().calibration; })
      .def_property_readonly("full_report", [](const PyFit& f) { return f.s().FullReport(); })
      .def_property_readonly("json_text", [](const PyFit& f) { return f.json; })
      .def("parameter_columns", [](const PyFit& f) { return ParameterColumns(f.s()); })
      .def("channel_rows", [](const PyFit& f) { return ChannelRows(f.s()); })
      .def("experiment_rows", [](const PyFit& f) { return ExperimentRows(f.s()); })
      .def("correlation",
           [](const PyFit& f) {
             std::vector<std::string> names;
             for (int i : f.s().estimated_positions) names.push_back(f.s().parameters.spec(i).key());
             return py::make_tuple(names, Eigen::MatrixXd(f.s().correlation));
           })
      .def(
          "write_report",
          [](const PyFit& f, const std::string& path, const std::string& title) {
            py::gil_scoped_release unlocked;
            report::WriteFitReport(f.s(), path, title);
          },
          py::arg("path"), py::arg("title"));

  m.def(
      "identify",
      [](const py::sequence& sessions, const py::dict& kwargs) {
        const ParsedCommand<tools::IdentifyCommand> parsed(&tools::AddIdentifyOptions, "identify", Words(sessions), kwargs);
        const tools::IdentifyCommand& command = parsed.command;
        ident::SessionFit fit;
        {
          py::gil_scoped_release unlocked;
          fit = command.Fit();
        }
        const nlohmann::json json = command.Json(fit);
        return MakeFit(std::move(fit.summary), json);
      },
      py::arg("sessions"), py::arg("kwargs"));

  py::class_<PyDiscovery>(m, "Discovery")
      .def_property_readonly("conclusion", [](const PyDiscovery& d) { return d.result->conclusion; })
      .def_property_readonly("missing", [](const PyDiscovery& d) { return d.result->missing; })
      .def_property_readonly("nothing_missing", [](const PyDiscovery& d) { return d.result->nothing_missing; })
      .def_property_readonly("final_model", [](const PyDiscovery& d) { return d.result->final_model; })
      .def_property_readonly("baseline",
                             [](const PyDiscovery& d) { return MakeFit(d.result->baseline, report::FitToJson(d.result->baseline)); })
      .def_property_readonly(
          "final_fit", [](const PyDiscovery& d) { return MakeFit(d.result->final_fit, report::FitToJson(d.result->final_fit)); })
      .def_property_readonly("json", [](const PyDiscovery& d) { return ToPythonJson(report::DiscoveryJson(*d.result)); })
      .def("write_report", [](const PyDiscovery& d, const std::string& path) {
        py::gil_scoped_release unlocked;
        report::WriteDiscoveryReport(*d.result, path);
      });

  m.def(
      "discover",
      [](const py::sequence& sessions, const py::dict& kwargs) {
        const ParsedCommand<tools::DiscoverCommand> parsed(&tools::AddDiscoverOptions, "discover", Words(sessions), kwargs);
        const tools::DiscoverCommand& command = parsed.command;
        py::gil_scoped_release unlocked;
        return PyDiscovery{std::make_shared<const ident::DiscoveryResult>(command.Discover())};
      },
      py::arg("sessions"), py::arg("kwargs"));

  py::class_<PyQc>(m, "QcDecision")
      .def_property_readonly("verdict", [](const PyQc& q) { return std::string(qc::ToString(q.outcome->decision.verdict)); })
      .def_property_readonly("reasons", [](const PyQc& q) { return q.outcome->decision.reasons; })
      .def_property_readonly("table", [](const PyQc& q) { return qc::Table(q.outcome->decision); })
      .def_property_readonly("json", [](const PyQc& q) { return ToPythonJson(report::QcToJson(q.outcome->decision)); })
      .def_property_readonly("fit",
                             [](const PyQc& q) -> py::object {
                               if (q.outcome->decision.fit_verdict.empty()) return py::none();
                               return py::cast(MakeFit(q.outcome->fit.summary, report::FitToJson(q.outcome->fit.summary)));
                             })
      .def("write_report", [](const PyQc& q, const std::string& path) {
        py::gil_scoped_release unlocked;
        const qc::Decision& d = q.outcome->decision;
        report::WriteQcReport(d, d.fit_verdict.empty() ? nullptr : &q.outcome->fit, path);
      });

  m.def(
      "qc",
      [](const std::string& session, const py::dict& kwargs) {
        const ParsedCommand<tools::QcCommand> parsed(&tools::AddQcOptions, "qc", {session}, kwargs);
        const tools::QcCommand& command = parsed.command;
        py::gil_scoped_release unlocked;
        return PyQc{std::make_shared<const tools::QcOutcome>(command.Decide())};
      },
      py::arg("session"), py::arg("kwargs"));

  py::class_<PyDrop>(m, "DropPrediction")
      .def_property_readonly("json", [](const PyDrop& d) { return ToPythonJson(report::DropJson(*d.drop)); })
      .def_property_readonly("table",
                             [](const PyDrop& d) {
                               const report::DropTable t = report::DropFigureTable(*d.drop);
                               return py::make_tuple(t.header, t.rows);
                             })
      .def_property_readonly("trace",
                             [](const PyDrop& d) {
                               const sim::DropTrace& t = d.drop->prediction.predicted.trace;
                               py::dict r;
                               r["time"] = Array(t.time);
                               r["stroke"] = Array(t.stroke);
                               r["force"] = Array(t.force);
                               if (!t.pressure.empty()) r["pressure"] = Array(t.pressure);
                               if (!t.temperature.empty()) r["temperature"] = Array(t.temperature);
                               return r;
                             })
      .def("write_report", [](const PyDrop& d, const std::string& path) {
        py::gil_scoped_release unlocked;
        report::WriteDropReport(*d.drop, path);
      });

  m.def(
      "predict_drop",
      [](const py::dict& kwargs) {
        const ParsedCommand<tools::PredictDropCommand> parsed(&tools::AddPredictDropOptions, "predict drop", {}, kwargs);
        const tools::PredictDropCommand& command = parsed.command;
        py::gil_scoped_release unlocked;
        return PyDrop{std::make_shared<const report::DropComparison>(command.Predict())};
      },
      py::arg("kwargs"));

  m.def(
      "sim_matrix",
      [](const py::dict& kwargs) {
        const ParsedCommand<tools::SimMatrixCommand> parsed(&tools::AddSimMatrixOptions, "sim matrix", {}, kwargs);
        const tools::SimMatrixCommand& command = parsed.command;
        daq::Session session;
        {
          py::gil_scoped_release unlocked;
          session = command.Record();
        }
        session.source_path = command.output;
        return SessionToPython(session);
      },
      py::arg("kwargs"));

  m.def(
      "sim_drop",
      [](const py::dict& kwargs) {
        const ParsedCommand<tools::SimDropCommand> parsed(&tools::AddSimDropOptions, "sim drop", {}, kwargs);
        const tools::SimDropCommand& command = parsed.command;
        daq::Session session;
        {
          py::gil_scoped_release unlocked;
          session = command.Record();
        }
        session.source_path = command.output;
        return SessionToPython(session);
      },
      py::arg("kwargs"));

  m.def(
      "options",
      [](const std::string& command) {
        CLI::App app{"strut " + command};
        tools::IdentifyCommand identify;
        tools::DiscoverCommand discover;
        tools::QcCommand qc;
        tools::PredictDropCommand predict;
        tools::SimMatrixCommand matrix;
        tools::SimDropCommand drop;
        if (command == "identify") tools::AddIdentifyOptions(app, identify);
        else if (command == "discover") tools::AddDiscoverOptions(app, discover);
        else if (command == "qc") tools::AddQcOptions(app, qc);
        else if (command == "predict drop") tools::AddPredictDropOptions(app, predict);
        else if (command == "sim matrix") tools::AddSimMatrixOptions(app, matrix);
        else if (command == "sim drop") tools::AddSimDropOptions(app, drop);
        else throw std::invalid_argument("no command '" + command + "' in the Python package");
        py::dict d;
        for (const auto& [keyword, o] : Keywords(app))
          d[py::str(keyword)] = py::dict(py::arg("option") = "--" + o->get_lnames().front(),
                                         py::arg("default") = o->get_default_str(),
                                         py::arg("flag") = o->get_expected_max() == 0,
                                         py::arg("required") = o->get_required(),
                                         py::arg("description") = o->get_description());
        return d;
      },
      py::arg("command"),
      "The keyword arguments of a command ('identify', 'predict drop', ...): option, default (as --help shows it), flag, "
      "required, description.");
}

}  // namespace strut::python
