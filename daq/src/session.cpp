// Session accessors and the contract checks shared by ReadSession, Validate and WriteSession.
#include "strut/daq/session.h"

#include <spdlog/fmt/fmt.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <iterator>
#include <set>

#include "session_check.h"

namespace strut::daq {

std::string_view ToString(ExperimentKind kind) {
  switch (kind) {
    case ExperimentKind::kPeriodic:
      return "periodic";
    case ExperimentKind::kDrop:
      return "drop";
    case ExperimentKind::kStatic:
      return "static";
    case ExperimentKind::kRecord:
      return "record";
  }
  return "unknown";
}

namespace {

// The element of `items` whose `key` is `name`, or nullptr.
template <typename T>
const T* FindBy(const std::vector<T>& items, std::string T::*key, std::string_view name) {
  const auto it = std::find_if(items.begin(), items.end(), [&](const T& x) { return x.*key == name; });
  return it == items.end() ? nullptr : &*it;
}

// Every element's `key`, separated by commas, for a message that says what there is.
template <typename T>
std::string Keys(const std::vector<T>& items, std::string T::*key) {
  std::vector<std::string_view> keys;
  for (const T& x : items) keys.push_back(x.*key);
  return fmt::format("{}", fmt::join(keys, ", "));
}

}  // namespace

const Channel* Experiment::find_channel(std::string_view name) const { return FindBy(channels, &Channel::name, name); }

const Channel& Experiment::channel(std::string_view name) const {
  if (const Channel* c = find_channel(name)) return *c;
  throw SessionError(
      fmt::format("experiment '{}': no channel '{}' (it has: {})", label, name, Keys(channels, &Channel::name)));
}

std::vector<double> Experiment::absolute_pressure() const {
  const Channel& p = channel("pressure");
  if (p.reference == "absolute") return p.samples;
  if (p.reference != "gauge") {
    throw SessionError(
        fmt::format("experiment '{}': channel 'pressure': reference '{}' is neither "
                    "\"absolute\" nor \"gauge\"",
                    label, p.reference));
  }
  std::vector<double> absolute(p.samples);
  for (double& v : absolute) v += kGaugeReferencePa;
  return absolute;
}

const Experiment* Session::find_experiment(std::string_view label) const {
  return FindBy(experiments, &Experiment::label, label);
}

const Experiment& Session::experiment(std::string_view label) const {
  if (const Experiment* e = find_experiment(label)) return *e;
  throw SessionError(fmt::format("{}: no experiment '{}' (it has: {})", source_path.empty() ? "<memory>" : source_path,
                                 label, Keys(experiments, &Experiment::label)));
}

const MetadataGroup* Session::find_metadata(std::string_view name) const {
  const auto it = std::find_if(metadata.begin(), metadata.end(),
                               [&](const MetadataGroup& g) { return g.name == name; });
  return it == metadata.end() ? nullptr : &*it;
}

const MetadataGroup* MetadataGroup::find_group(std::string_view group_name) const {
  const auto it = std::find_if(groups.begin(), groups.end(),
                               [&](const MetadataGroup& g) { return g.name == group_name; });
  return it == groups.end() ? nullptr : &*it;
}

std::optional<double> MetadataGroup::number(std::string_view attribute) const {
  const auto it = attributes.find(std::string(attribute));
  if (it == attributes.end()) return std::nullopt;
  if (const double* d = std::get_if<double>(&it->second)) return *d;
  if (const long long* i = std::get_if<long long>(&it->second)) return static_cast<double>(*i);
  return std::nullopt;
}

std::optional<std::string> MetadataGroup::text(std::string_view attribute) const {
  const auto it = attributes.find(std::string(attribute));
  if (it == attributes.end()) return std::nullopt;
  if (const std::string* t = std::get_if<std::string>(&it->second)) return *t;
  return std::nullopt;
}

std::vector<std::string> Validate(const Session& session) {
  detail::DefectList defects(session.source_path.empty() ? "<memory>" : session.source_path);
  detail::CheckSession(session, defects);
  return defects.messages();
}

std::string UtcNowIso8601() {
  const std::time_t now = std::chrono::system_clock::to_time_t(std::chrono::system_clock::now());
  std::tm utc{};
  gmtime_r(&now, &utc);
  std::array<char, 32> text{};
  const std::size_t n = std::strftime(text.data(), text.size(), "%Y-%m-%dT%H:%M:%SZ", &utc);
  return std::string(text.data(), n);
}

std::optional<double> ParseUtcIso8601(const std::string& text) {
  std::tm utc{};
  double seconds = 0.0;
  char zone = 0;
  int consumed = 0;
  if (std::sscanf(text.c_str(), "%4d-%2d-%2dT%2d:%2d:%lf%c%n", &utc.tm_year, &utc.tm_mon, &utc.tm_mday, &utc.tm_hour,
                  &utc.tm_min, &seconds, &zone, &consumed) != 7 ||
      zone != 'Z' || consumed != static_cast<int>(text.size()) || !(seconds >= 0.0 && seconds < 61.0) ||
      utc.tm_mon < 1 || utc.tm_mon > 12 || utc.tm_mday < 1 || utc.tm_mday > 31 || utc.tm_hour > 23 || utc.tm_min > 59)
    return std::nullopt;
  utc.tm_year -= 1900;
  utc.tm_mon -= 1;
  const double whole = std::floor(seconds);
  utc.tm_sec = static_cast<int>(whole);
  return static_cast<double>(timegm(&utc)) + (seconds - whole);
}

std::vector<double> ExperimentSessionTimes(const Session& session) {
  const std::size_t count = session.experiments.size();
  std::vector<double> times(count, 0.0);
  if (count < 2) return times;
  std::vector<double> utc;
  for (const Experiment& e : session.experiments) {
    const auto it = e.extra_attributes.find("started_utc");
    const std::optional<double> t = it == e.extra_attributes.end() ? std::nullopt : ParseUtcIso8601(it->second);
    if (!t) break;
    utc.push_back(*t);
  }
  if (utc.size() == count) {
    const auto [first, last] = std::minmax_element(utc.begin(), utc.end());
    if (*last > *first) {
      for (std::size_t i = 0; i < count; ++i) times[i] = (utc[i] - *first) / (*last - *first);
      return times;
    }
  }
  for (std::size_t i = 0; i < count; ++i) times[i] = OrderSessionTime(i, count);
  return times;
}

double OrderSessionTime(std::size_t index, std::size_t count) {
  return count < 2 ? 0.0 : static_cast<double>(index) / static_cast<double>(count - 1);
}

namespace {

constexpr std::string_view kCalibrationGroup = "calibration";

struct ZeroAttributes {
  const char* value;
  const char* sd;
};
constexpr ZeroAttributes kLoadCellZero{"load_cell_zero", "load_cell_zero_sd"};
constexpr ZeroAttributes kStrokeZero{"stroke_zero", "stroke_zero_sd"};

std::optional<MeasuredZero> ReadZero(const MetadataGroup& group, const ZeroAttributes& names, const std::string& file) {
  const auto fail = [&](const char* attribute, std::string_view what) {
    return SessionError(fmt::format("{}: group '/{}', attribute '{}': {}", file, kCalibrationGroup, attribute, what));
  };
  if (!group.attributes.count(names.value)) {
    if (group.attributes.count(names.sd)) throw fail(names.value, fmt::format("missing beside '{}'", names.sd));
    return std::nullopt;
  }
  const std::optional<double> value = group.number(names.value);
  if (!value || !std::isfinite(*value)) throw fail(names.value, "not a finite number");
  const std::optional<double> sd = group.number(names.sd);
  if (!group.attributes.count(names.sd)) throw fail(names.sd, fmt::format("missing: '{}' needs the sd it is known to", names.value));
  if (!sd || !std::isfinite(*sd) || !(*sd > 0.0)) throw fail(names.sd, "not a positive number");
  return MeasuredZero{*value, *sd};
}

}  // namespace

RecordedZeros ReadRecordedZeros(const Session& session) {
  RecordedZeros zeros;
  const MetadataGroup* group = session.find_metadata(kCalibrationGroup);
  if (!group) return zeros;
  const std::string file = session.source_path.empty() ? "<memory>" : session.source_path;
  zeros.load_cell = ReadZero(*group, kLoadCellZero, file);
  zeros.stroke = ReadZero(*group, kStrokeZero, file);
  return zeros;
}

void RecordZeros(const RecordedZeros& zeros, Session& session) {
  std::erase_if(session.metadata, [](const MetadataGroup& g) { return g.name == kCalibrationGroup; });
  if (zeros.empty()) return;
  MetadataGroup group;
  group.name = std::string(kCalibrationGroup);
  const auto put = [&](const std::optional<MeasuredZero>& zero, const ZeroAttributes& names) {
    if (!zero) return;
    group.attributes[names.value] = zero->value;
    group.attributes[names.sd] = zero->sd;
  };
  put(zeros.load_cell, kLoadCellZero);
  put(zeros.stroke, kStrokeZero);
  session.metadata.push_back(std::move(group));
}

std::optional<long> WholeSamplesPerPeriod(double sample_rate, double frequency, long minimum) {
  if (!(sample_rate > 0.0) || !(frequency > 0.0)) return std::nullopt;
  const double n = sample_rate / frequency;
  const double rounded = std::round(n);
  if (rounded < static_cast<double>(minimum) || std::abs(n - rounded) > kWholeSamplesTolerance * n) return std::nullopt;
  return static_cast<long>(rounded);
}

namespace detail {

std::optional<std::string> PeriodCountDefect(const Experiment& e, std::size_t samples) {
  const double exact = static_cast<double>(e.periods) * e.sample_rate / e.frequency;
  const long long expected = std::llround(exact);
  const long long actual = static_cast<long long>(samples);
  if (std::llabs(actual - expected) <= 1) return std::nullopt;
  return fmt::format("{} samples, but periods * sample_rate / frequency = {} * {} / {} = {} (±1 accepted)",
                     actual, e.periods, e.sample_rate, e.frequency, expected);
}

namespace {

// Accepted unit symbols: SI only, so that no reader has to guess a scale factor.
constexpr std::array<std::string_view, 12> kKnownUnits = {"m", "N",   "Pa",    "K",    "s",  "V",
                                                          "A", "m/s", "m/s^2", "m/s2", "kg", "1"};

// Above this relative difference between the time axis and sample_rate a file is rejected;
// above kRateWarning it only gets a warning (a slightly drifting DAQ clock).
constexpr double kRateTolerance = 0.01;
constexpr double kRateWarning = 0.001;
// A single time step this far from 1/sample_rate means dropped or repeated samples.
constexpr double kStepTolerance = 0.5;
// Single steps off by more than this (but less than kStepTolerance) are jitter: a warning.
constexpr double kStepWarning = 0.01;

bool IsValidName(std::string_view name) {
  return !name.empty() && name != "." && name.find('/') == std::string_view::npos;
}

bool StartsWithDate(std::string_view text) {
  // YYYY-MM-DD or the basic form YYYYMMDD.
  auto digits = [&](std::size_t from, std::size_t count) {
    if (text.size() < from + count) return false;
    return std::all_of(text.begin() + from, text.begin() + from + count,
                       [](char c) { return c >= '0' && c <= '9'; });
  };
  return (digits(0, 4) && text.size() >= 10 && text[4] == '-' && digits(5, 2) && text[7] == '-' &&
          digits(8, 2)) ||
         digits(0, 8);
}

// Counts NaN/Inf samples; `first` gets the index of the first one.
std::size_t CountNonFinite(const std::vector<double>& samples, std::size_t& first) {
  std::size_t count = 0;
  for (std::size_t i = 0; i < samples.size(); ++i) {
    if (!std::isfinite(samples[i])) {
      if (count == 0) first = i;
      ++count;
    }
  }
  return count;
}

std::string NonFiniteMessage(std::size_t count, std::size_t first) {
  return fmt::format("{} NaN/Inf sample{} (first at index {})", count, count == 1 ? "" : "s",
                     first);
}

class ExperimentChecker {
 public:
  ExperimentChecker(const Experiment& e, DefectList& defects, bool generic)
      : e_(e), defects_(defects), generic_(generic) {}

  void Run() {
    CheckAttributes();
    const bool time_ok = CheckTime();
    CheckChannels(time_ok);
    if (time_ok) CheckPeriodCount();
  }

 private:
  bool Has(std::string_view item) const { return defects_.Has(e_.label, item); }
  void Add(std::string_view item, std::string_view what) { defects_.Add(e_.label, item, what); }

  // True when the attribute was read and is a finite number > 0 (reports it otherwise).
  bool Positive(std::string_view name, double value) {
    const std::string item = AttributeItem(name);
    if (Has(item)) return false;
    if (std::isfinite(value) && value > 0) return true;
    Add(item, fmt::format("must be > 0, found {}", value));
    return false;
  }

  void CheckAttributes() {
    // An unknown kind was reported by the reader; kind-specific checks would only add noise.
    kind_ok_ = !Has(AttributeItem("kind"));
    const std::string status_item = AttributeItem("status");
    if (!Has(status_item) && e_.status != "complete" && e_.status != "aborted") {
      Add(status_item, fmt::format("'{}' is neither \"complete\" nor \"aborted\"", e_.status));
    }
    rate_ok_ = Positive("sample_rate", e_.sample_rate);

    if (!kind_ok_) return;
    if (e_.kind == ExperimentKind::kRecord && !generic_) {
      Add(AttributeItem("kind"), "\"record\" needs the session profile \"generic\"");
    }
    if (e_.kind == ExperimentKind::kPeriodic && generic_) {
      // Generic profile: any excitation; amplitude and static position are optional (0: none).
      frequency_ok_ = Positive("frequency", e_.frequency);
      const std::string waveform_item = AttributeItem("waveform");
      if (!Has(waveform_item) && e_.waveform.empty()) Add(waveform_item, "empty");
      const std::pair<const char*, double> optional[] = {{"amplitude", e_.amplitude},
                                                         {"static_position", e_.static_position}};
      for (const auto& [name, value] : optional) {
        if (!Has(AttributeItem(name)) && !std::isfinite(value)) {
          Add(AttributeItem(name), fmt::format("must be finite, found {}", value));
        }
      }
      CheckPeriods();
    } else if (e_.kind == ExperimentKind::kPeriodic) {
      frequency_ok_ = Positive("frequency", e_.frequency);
      Positive("amplitude", e_.amplitude);
      const std::string position_item = AttributeItem("static_position");
      // A stroke is compression-positive from full extension, so never negative.
      if (!Has(position_item) && !(std::isfinite(e_.static_position) && e_.static_position >= 0)) {
        Add(position_item, fmt::format("must be >= 0 (a stroke), found {}", e_.static_position));
      }
      const std::string waveform_item = AttributeItem("waveform");
      if (!Has(waveform_item) && e_.waveform != "sine") {
        Add(waveform_item, fmt::format("'{}' is not supported (only \"sine\")", e_.waveform));
      }
      CheckPeriods();
    } else if (e_.kind == ExperimentKind::kDrop) {
      Positive("drop_mass", e_.drop_mass);
      Positive("impact_velocity", e_.impact_velocity);
    }

    for (const auto& [name, value] : e_.extra_attributes) {
      const std::string item = AttributeItem(name);
      if (name.empty()) {
        Add("extra attributes", "an extra attribute has an empty name");
      } else if (IsContractAttribute(e_.kind, name)) {
        Add(item, "extra attribute has the name of a contract attribute");
      }
    }
  }

  void CheckPeriods() {
    // An aborted experiment may hold no steady-state period at all.
    const std::string periods_item = AttributeItem("periods");
    const long min_periods = e_.status == "aborted" ? 0 : 1;
    if (!Has(periods_item)) {
      if (e_.periods >= min_periods) {
        periods_ok_ = true;
      } else {
        Add(periods_item, fmt::format("must be >= {}, found {}", min_periods, e_.periods));
      }
    }
  }

  // Checks the time axis; true when it can serve as the length reference.
  bool CheckTime() {
    if (Has(kTimeItem)) return false;
    const std::vector<double>& t = e_.time;
    if (t.empty()) {
      if (!Has(kSamplesItem)) Add(kSamplesItem, "no samples (empty experiment)");
      return false;
    }
    std::size_t first = 0;
    if (const std::size_t bad = CountNonFinite(t, first); bad > 0) {
      Add(kTimeItem, NonFiniteMessage(bad, first));
      return true;  // the length is still right
    }
    for (std::size_t i = 1; i < t.size(); ++i) {
      if (!(t[i] > t[i - 1])) {
        Add(kTimeItem,
            fmt::format("not increasing at index {} ({} s after {} s)", i, t[i], t[i - 1]));
        return true;
      }
    }
    if (!rate_ok_) return true;
    const double step = 1.0 / e_.sample_rate;
    if (std::abs(t.front()) > 0.5 * step) {
      Add(kTimeItem,
          fmt::format("starts at {} s, not at 0 (the first recorded sample)", t.front()));
    }
    if (t.size() < 2) return true;

    const double mean_step = (t.back() - t.front()) / static_cast<double>(t.size() - 1);
    const double rate_error = mean_step / step - 1.0;
    if (std::abs(rate_error) > kRateTolerance) {
      Add(kTimeItem, fmt::format("mean step {:.6g} s is {:+.2f}% off 1/sample_rate = {:.6g} s "
                                 "(tolerance {}%)",
                                 mean_step, 100 * rate_error, step, 100 * kRateTolerance));
      return true;
    }
    if (std::abs(rate_error) > kRateWarning) {
      defects_.Warn(e_.label, kTimeItem,
                    fmt::format("mean step {:.6g} s is {:+.3f}% off 1/sample_rate = {:.6g} s "
                                "(accepted up to {}%)",
                                mean_step, 100 * rate_error, step, 100 * kRateTolerance));
    }
    std::size_t gaps = 0, jitter = 0, first_gap = 0;
    for (std::size_t i = 1; i < t.size(); ++i) {
      const double error = std::abs((t[i] - t[i - 1]) / step - 1.0);
      if (error > kStepTolerance) {
        if (gaps++ == 0) first_gap = i;
      } else if (error > kStepWarning) {
        ++jitter;
      }
    }
    if (gaps > 0) {
      Add(kTimeItem, fmt::format("{} {} from 1/sample_rate = {:.6g} s by more than {}% "
                                 "(first at index {}: {:.6g} s): dropped or repeated samples",
                                 gaps, gaps == 1 ? "step differs" : "steps differ", step,
                                 100 * kStepTolerance, first_gap, t[first_gap] - t[first_gap - 1]));
    } else if (jitter > 0) {
      defects_.Warn(e_.label, kTimeItem,
                    fmt::format("{} {} from 1/sample_rate by more than {}% (jitter)", jitter,
                                jitter == 1 ? "step differs" : "steps differ", 100 * kStepWarning));
    }
    return true;
  }

  void CheckChannels(bool time_ok) {
    std::set<std::string_view> seen;
    // The generic profile names its own channels; it needs at least one.
    for (std::string_view name : kStandardChannels) {
      const std::string item = ChannelItem(name);
      if (!generic_ && e_.find_channel(name) == nullptr && !Has(item)) Add(item, "missing");
    }
    if (generic_ && e_.channels.empty() && !Has("channels")) Add("channels", "none (a generic experiment needs one)");
    for (const Channel& c : e_.channels) {
      const std::string item = ChannelItem(c.name);
      if (!IsValidName(c.name) || c.name == "time") {
        Add(item, "invalid channel name (empty, '.', 'time' or containing '/')");
        continue;
      }
      if (!seen.insert(c.name).second) {
        Add(item, "appears more than once");
        continue;
      }
      CheckUnits(c);
      CheckReference(c);
      if (Has(item)) continue;
      if (time_ok && c.samples.size() != e_.time.size()) {
        Add(item, fmt::format("{} samples, but 'time' has {}", c.samples.size(), e_.time.size()));
        continue;
      }
      std::size_t first = 0;
      if (const std::size_t bad = CountNonFinite(c.samples, first); bad > 0) {
        Add(item, NonFiniteMessage(bad, first));
      }
    }
  }

  void CheckUnits(const Channel& c) {
    const std::string item = ChannelAttributeItem(c.name, "units");
    if (Has(item)) return;
    const std::string_view expected = ExpectedUnits(c.name);
    if (c.units.empty()) {
      Add(item, "empty (an SI unit symbol is required)");
    } else if (!IsKnownUnit(c.units)) {
      Add(item,
          fmt::format("unknown units '{}' (accepted: {})", c.units, fmt::join(kKnownUnits, ", ")));
    } else if (!expected.empty() && c.units != expected) {
      Add(item, fmt::format("'{}', expected '{}'", c.units, expected));
    }
  }

  void CheckReference(const Channel& c) {
    const std::string item = ChannelAttributeItem(c.name, "reference");
    if (Has(item)) return;
    if (c.name == "pressure") {
      if (c.reference.empty()) {
        Add(item, "missing (must be \"absolute\" or \"gauge\")");
      } else if (c.reference != "absolute" && c.reference != "gauge") {
        Add(item, fmt::format("'{}' is neither \"absolute\" nor \"gauge\"", c.reference));
      }
    } else if (!c.reference.empty()) {
      Add(item, "only the pressure channel has a reference");
    }
  }

  // Contract: a periodic recording covers exactly `periods` whole periods.
  void CheckPeriodCount() {
    if (!kind_ok_ || e_.kind != ExperimentKind::kPeriodic || !rate_ok_ || !frequency_ok_ ||
        !periods_ok_)
      return;
    if (e_.periods == 0 || Has(kSamplesItem)) return;
    if (auto defect = PeriodCountDefect(e_, e_.time.size())) Add(kSamplesItem, *defect);
  }

  const Experiment& e_;
  DefectList& defects_;
  bool generic_ = false;
  bool kind_ok_ = false;
  bool rate_ok_ = false;
  bool frequency_ok_ = false;
  bool periods_ok_ = false;
};

}  // namespace

void DefectList::Add(std::string_view experiment, std::string_view item, std::string_view what) {
  messages_.push_back(Prefix(experiment, item) + std::string(what));
  items_.emplace(std::string(experiment), std::string(item));
}

bool DefectList::Has(std::string_view experiment, std::string_view item) const {
  return items_.count({std::string(experiment), std::string(item)}) > 0;
}

void DefectList::Warn(std::string_view experiment, std::string_view item,
                      std::string_view what) const {
  spdlog::warn("{}{}", Prefix(experiment, item), what);
}

std::string DefectList::Joined() const { return fmt::format("{}", fmt::join(messages_, "\n")); }

std::string DefectList::Prefix(std::string_view experiment, std::string_view item) const {
  if (experiment.empty()) return fmt::format("{}: {}: ", file_, item);
  return fmt::format("{}: experiment '{}': {}: ", file_, experiment, item);
}

std::string AttributeItem(std::string_view name) { return fmt::format("attribute '{}'", name); }

std::string ChannelItem(std::string_view name) { return fmt::format("channel '{}'", name); }

std::string ChannelAttributeItem(std::string_view channel, std::string_view attribute) {
  return fmt::format("channel '{}': attribute '{}'", channel, attribute);
}

std::string_view ExpectedUnits(std::string_view channel) {
  if (channel == "time") return "s";
  if (channel == "stroke") return "m";
  if (channel == "force") return "N";
  if (channel == "pressure") return "Pa";
  return {};
}

bool IsKnownUnit(std::string_view units) {
  return std::find(kKnownUnits.begin(), kKnownUnits.end(), units) != kKnownUnits.end();
}

bool IsContractAttribute(ExperimentKind kind, std::string_view name) {
  if (name == "kind" || name == "status" || name == "sample_rate") return true;
  if (kind == ExperimentKind::kPeriodic) {
    return name == "frequency" || name == "amplitude" || name == "static_position" ||
           name == "waveform" || name == "periods" || name == "group";
  }
  if (kind == ExperimentKind::kDrop) return name == "drop_mass" || name == "impact_velocity";
  return false;
}

void SortChannels(std::vector<Channel>& channels) {
  auto rank = [](const Channel& c) {
    const auto* it = std::find(std::begin(kStandardChannels), std::end(kStandardChannels), c.name);
    return static_cast<int>(it - std::begin(kStandardChannels));
  };
  std::stable_sort(channels.begin(), channels.end(), [&](const Channel& a, const Channel& b) {
    const int ra = rank(a), rb = rank(b);
    return ra != rb ? ra < rb : a.name < b.name;
  });
}

void CheckSession(const Session& session, DefectList& defects) {
  const std::string profile_item = AttributeItem("profile");
  if (!defects.Has("", profile_item) && session.profile != kDamperProfile && session.profile != kGenericProfile) {
    defects.Add("", profile_item,
                fmt::format("'{}' is neither \"{}\" nor \"{}\"", session.profile, kDamperProfile, kGenericProfile));
  }
  const std::string version_item = AttributeItem("format_version");
  if (!defects.Has("", version_item) && session.format_version != 1) {
    defects.Add(
        "", version_item,
        fmt::format("unsupported version {} (strut reads version 1)", session.format_version));
  }
  const std::pair<std::string_view, const std::string*> texts[] = {
      {"created_utc", &session.created_utc},
      {"damper_serial", &session.damper_serial},
      {"rig", &session.rig}};
  for (const auto& [name, value] : texts) {
    const std::string item = AttributeItem(name);
    if (!defects.Has("", item) && value->empty()) defects.Add("", item, "empty");
  }
  if (!session.created_utc.empty() && !StartsWithDate(session.created_utc)) {
    defects.Warn("", AttributeItem("created_utc"),
                 fmt::format("'{}' does not look like an ISO 8601 time", session.created_utc));
  }
  // Extra root groups: valid, unique link names that are not the contract's /experiments.
  const auto check_groups = [&](const auto& self, const std::vector<MetadataGroup>& groups,
                                const std::string& parent) -> void {
    std::set<std::string_view> names;
    for (const MetadataGroup& g : groups) {
      const std::string item = fmt::format("group '{}/{}'", parent, g.name);
      if (!IsValidName(g.name) || (parent.empty() && g.name == "experiments")) {
        defects.Add("", item, "invalid name (empty, '.', with '/', or the contract's 'experiments')");
      } else if (!names.insert(g.name).second) {
        defects.Add("", item, "used by more than one group");
      }
      for (const auto& [name, value] : g.attributes) {
        if (!IsValidName(name)) defects.Add("", item, fmt::format("attribute '{}': invalid name", name));
      }
      self(self, g.groups, parent + "/" + g.name);
    }
  };
  check_groups(check_groups, session.metadata, "");
  if (session.experiments.empty() && !defects.Has("", kExperimentsItem)) {
    defects.Warn("", kExperimentsItem, "no experiments");
  }

  std::set<std::string_view> labels;
  for (const Experiment& e : session.experiments) {
    if (!IsValidName(e.label)) {
      defects.Add("", "experiment label",
                  fmt::format("'{}' is empty, '.' or contains '/'", e.label));
      continue;
    }
    if (!labels.insert(e.label).second) {
      defects.Add(e.label, "label", "used by more than one experiment");
      continue;
    }
    ExperimentChecker(e, defects, session.generic()).Run();
  }
}

}  // namespace detail
bool IsRecordingChannel(const Channel& channel) {
  if (channel.units != "1") return false;
  const std::string_view name = channel.name;
  constexpr std::string_view kCounts = "_counts";
  return name == "sequence" || name == "status" ||
         (name.size() > kCounts.size() && name.substr(name.size() - kCounts.size()) == kCounts);
}

}  // namespace strut::daq
