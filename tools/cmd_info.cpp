// strut info SESSION [--json]: validates a session file and lists its experiments.
#include <spdlog/fmt/fmt.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "commands.h"
#include "strut/daq/session.h"

namespace strut::tools {
namespace {

struct InfoOptions {
  std::string path;
  bool json = false;
};

// While alive, log to stderr so that stdout holds nothing but the JSON document.
class LogToStderr {
 public:
  LogToStderr() : previous_(spdlog::default_logger()) {
    auto logger = std::make_shared<spdlog::logger>(
        previous_->name(), std::make_shared<spdlog::sinks::stderr_color_sink_mt>());
    logger->set_level(previous_->level());
    logger->set_pattern("%^[%l]%$ %v");  // as main.cpp sets it
    spdlog::set_default_logger(std::move(logger));
  }
  ~LogToStderr() { spdlog::set_default_logger(previous_); }
  LogToStderr(const LogToStderr&) = delete;
  LogToStderr& operator=(const LogToStderr&) = delete;

 private:
  std::shared_ptr<spdlog::logger> previous_;
};

std::vector<std::string> Lines(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

std::string ChannelText(const daq::Channel& c) {
  if (c.reference.empty()) return fmt::format("{}[{}]", c.name, c.units);
  return fmt::format("{}[{}, {}]", c.name, c.units, c.reference);
}

nlohmann::ordered_json ExperimentJson(const daq::Experiment& e) {
  const bool periodic = e.kind == daq::ExperimentKind::kPeriodic;
  nlohmann::ordered_json channels = nlohmann::ordered_json::array();
  for (const daq::Channel& c : e.channels) {
    nlohmann::ordered_json channel = {{"name", c.name}, {"units", c.units}};
    if (!c.reference.empty()) channel["reference"] = c.reference;
    channels.push_back(std::move(channel));
  }
  nlohmann::ordered_json j = {
      {"label", e.label},
      {"kind", std::string(daq::ToString(e.kind))},
      {"status", e.status},
      {"group",
       periodic && !e.group.empty() ? nlohmann::ordered_json(e.group) : nlohmann::ordered_json()},
      {"frequency", periodic ? nlohmann::ordered_json(e.frequency) : nlohmann::ordered_json()},
      {"amplitude", periodic ? nlohmann::ordered_json(e.amplitude) : nlohmann::ordered_json()},
      {"static_position",
       periodic ? nlohmann::ordered_json(e.static_position) : nlohmann::ordered_json()},
      {"periods", periodic ? nlohmann::ordered_json(e.periods) : nlohmann::ordered_json()},
      {"samples", e.sample_count()},
      {"sample_rate", e.sample_rate},
      {"channels", std::move(channels)},
  };
  if (e.kind == daq::ExperimentKind::kDrop) {
    j["drop_mass"] = e.drop_mass;
    j["impact_velocity"] = e.impact_velocity;
  }
  if (!e.extra_attributes.empty()) j["extra_attributes"] = e.extra_attributes;
  return j;
}

nlohmann::ordered_json SessionJson(const daq::Session& s) {
  nlohmann::ordered_json experiments = nlohmann::ordered_json::array();
  for (const daq::Experiment& e : s.experiments) experiments.push_back(ExperimentJson(e));
  return {{"file", s.source_path},
          {"format_version", s.format_version},
          {"created_utc", s.created_utc},
          {"damper_serial", s.damper_serial},
          {"rig", s.rig},
          {"valid", true},
          {"experiments", std::move(experiments)}};
}

// One row of text cells per experiment under a header, columns padded to their widest cell.
void PrintTable(const daq::Session& s) {
  std::vector<std::vector<std::string>> rows = {{"label", "kind", "status", "group", "f [Hz]",
                                                 "ampl [mm]", "static [mm]", "periods", "samples",
                                                 "rate [Hz]", "channels"}};
  for (const daq::Experiment& e : s.experiments) {
    const bool periodic = e.kind == daq::ExperimentKind::kPeriodic;
    auto if_periodic = [&](std::string text) { return periodic ? std::move(text) : "-"; };
    std::vector<std::string> channels;
    for (const daq::Channel& c : e.channels) channels.push_back(ChannelText(c));
    rows.push_back({e.label, std::string(daq::ToString(e.kind)), e.status,
                    periodic && !e.group.empty() ? e.group : "-",
                    if_periodic(fmt::format("{:g}", e.frequency)),
                    if_periodic(fmt::format("{:g}", e.amplitude * 1e3)),
                    if_periodic(fmt::format("{:g}", e.static_position * 1e3)),
                    if_periodic(std::to_string(e.periods)), std::to_string(e.sample_count()),
                    fmt::format("{:g}", e.sample_rate),
                    fmt::format("{}", fmt::join(channels, " "))});
  }
  std::vector<std::size_t> widths(rows.front().size(), 0);
  for (const auto& row : rows) {
    for (std::size_t i = 0; i < row.size(); ++i) widths[i] = std::max(widths[i], row[i].size());
  }
  for (const auto& row : rows) {
    std::string line;
    for (std::size_t i = 0; i < row.size(); ++i) {
      const bool last = i + 1 == row.size();
      line += last ? row[i] : fmt::format("{:<{}}  ", row[i], widths[i]);
    }
    std::cout << line << '\n';
  }
}

void PrintText(const daq::Session& s) {
  std::cout << fmt::format("file           {}\n", s.source_path)
            << fmt::format("format         damper-session, version {}\n", s.format_version)
            << fmt::format("created (UTC)  {}\n", s.created_utc)
            << fmt::format("damper serial  {}\n", s.damper_serial)
            << fmt::format("rig            {}\n", s.rig)
            << fmt::format("experiments    {} (file is valid)\n\n", s.experiments.size());
  if (!s.experiments.empty()) PrintTable(s);
}

void RunInfo(const InfoOptions& options) {
  std::optional<LogToStderr> log_to_stderr;
  if (options.json) log_to_stderr.emplace();
  try {
    const daq::Session session = daq::ReadSession(options.path);
    if (options.json) {
      std::cout << SessionJson(session).dump(2) << '\n';
    } else {
      PrintText(session);
    }
  } catch (const daq::SessionError& error) {
    const std::vector<std::string> lines = Lines(error.what());
    if (options.json) {  // the errors travel in the JSON document only
      const nlohmann::ordered_json report = {
          {"file", options.path}, {"valid", false}, {"errors", lines}};
      std::cout << report.dump(2) << '\n';
    } else {
      for (const std::string& line : lines) spdlog::error("{}", line);
    }
    throw CLI::RuntimeError(1);  // exit code 1; main prints nothing more for it
  }
}

}  // namespace

void RegisterInfoCommand(CLI::App& app) {
  auto options = std::make_shared<InfoOptions>();
  CLI::App* info =
      app.add_subcommand("info", "Validate a session file and list its attributes and experiments (a table, or JSON with --json).");
  info->add_option("SESSION", options->path, "The session file (HDF5, damper-session format).")
      ->required();
  info->add_flag("--json", options->json, "Print one JSON object (SI units) instead of a table; errors go into it too.");
  info->callback([options] { RunInfo(*options); });
}

}  // namespace strut::tools
