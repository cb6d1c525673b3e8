// The recorder's journal: record encoding, and reading a journal (whole or torn) back into the
// session Close and `strut recover` write.
#include "journal.h"

#include <spdlog/fmt/fmt.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <deque>
#include <map>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "session_check.h"

namespace strut::daq {

static_assert(std::endian::native == std::endian::little, "the journal is little-endian");

std::string_view ToString(EndStatus status) {
  switch (status) {
    case EndStatus::kComplete:
      return "complete";
    case EndStatus::kAborted:
      return "aborted";
    case EndStatus::kNotSteady:
      return "not-steady";
  }
  return "unknown";
}

std::string JournalPath(const std::string& session_path) { return session_path + ".journal"; }

namespace journal {

using nlohmann::json;

std::uint32_t Crc32(std::span<const std::byte> bytes, std::uint32_t crc) {
  static const std::array<std::uint32_t, 256> table = [] {
    std::array<std::uint32_t, 256> t{};
    for (std::uint32_t i = 0; i < 256; ++i) {
      std::uint32_t c = i;
      for (int k = 0; k < 8; ++k) c = (c & 1) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
      t[i] = c;
    }
    return t;
  }();
  crc = ~crc;
  for (std::byte b : bytes) crc = table[(crc ^ std::to_integer<std::uint32_t>(b)) & 0xFF] ^ (crc >> 8);
  return ~crc;
}

namespace {

template <typename T>
void Put(std::vector<std::byte>& out, const T& value) {
  const auto* p = reinterpret_cast<const std::byte*>(&value);
  out.insert(out.end(), p, p + sizeof(T));
}

template <typename T>
void PutArray(std::vector<std::byte>& out, const std::vector<T>& values) {
  const auto* p = reinterpret_cast<const std::byte*>(values.data());
  out.insert(out.end(), p, p + values.size() * sizeof(T));
}

// Appends the CRC of everything in `record` (size, type and payload).
void Seal(std::vector<std::byte>& record) { Put(record, Crc32(record)); }

json AttributeJson(const AttributeValue& value) {
  if (const double* d = std::get_if<double>(&value)) return {{"f", *d}};
  if (const long long* i = std::get_if<long long>(&value)) return {{"i", *i}};
  return {{"s", std::get<std::string>(value)}};
}

AttributeValue AttributeFromJson(const json& j) {
  if (j.contains("i")) return j.at("i").get<long long>();
  if (j.contains("s")) return j.at("s").get<std::string>();
  const json& f = j.at("f");
  return f.is_null() ? std::nan("") : f.get<double>();  // JSON has no NaN: it was written as null
}

json GroupJson(const MetadataGroup& group) {
  json attributes = json::object();
  for (const auto& [name, value] : group.attributes) attributes[name] = AttributeJson(value);
  json groups = json::array();
  for (const MetadataGroup& g : group.groups) groups.push_back(GroupJson(g));
  return {{"name", group.name}, {"attributes", attributes}, {"groups", groups}};
}

}  // namespace

MetadataGroup GroupFromJson(const json& j) {
  MetadataGroup group;
  group.name = j.at("name").get<std::string>();
  for (const auto& [name, value] : j.at("attributes").items()) {
    group.attributes.emplace(name, AttributeFromJson(value));
  }
  for (const json& g : j.at("groups")) group.groups.push_back(GroupFromJson(g));
  return group;
}


std::vector<std::byte> Header() {
  std::vector<std::byte> out;
  const auto* magic = reinterpret_cast<const std::byte*>(kMagic);
  out.insert(out.end(), magic, magic + sizeof kMagic);
  Put(out, kVersion);
  Put(out, std::uint32_t{0});
  return out;
}

std::vector<std::byte> Record(RecordType type, std::span<const std::byte> payload) {
  std::vector<std::byte> out;
  out.reserve(payload.size() + kRecordOverhead);
  Put(out, static_cast<std::uint32_t>(payload.size()));
  Put(out, static_cast<std::uint16_t>(type));
  Put(out, std::uint16_t{0});
  out.insert(out.end(), payload.begin(), payload.end());
  Seal(out);
  return out;
}

std::vector<std::byte> Record(RecordType type, const std::string& json_text) {
  return Record(type, std::as_bytes(std::span(json_text.data(), json_text.size())));
}

std::string OpenPayload(const RecordingMetadata& m, const std::string& created_utc,
                        std::int64_t monotonic_ns, std::int64_t utc_ns) {
  json groups = json::array();
  for (const MetadataGroup& g : m.groups) groups.push_back(GroupJson(g));
  return json{{"created_utc", created_utc},      {"damper_serial", m.damper_serial},
              {"rig", m.rig},                    {"operator", m.operator_name},
              {"software_version", m.software_version}, {"matrix", m.matrix},
              {"limits", m.limits},              {"profile", m.profile},
              {"groups", groups},                {"monotonic_ns", monotonic_ns},
              {"utc_ns", utc_ns}}
      .dump();
}

std::string BeginPayload(const ExperimentDescriptor& d) {
  const Experiment& e = d.header;
  json channels = json::array();
  for (const Channel& c : e.channels) {
    channels.push_back({{"name", c.name}, {"units", c.units}, {"reference", c.reference}});
  }
  json raw = json::array();
  for (const RawChannel& r : d.raw) {
    raw.push_back({{"channel", r.channel},
                   {"gain", r.calibration.gain},
                   {"offset", r.calibration.offset},
                   {"range_min", r.calibration.range_min},
                   {"range_max", r.calibration.range_max}});
  }
  return json{{"label", e.label},
              {"kind", ToString(e.kind)},
              {"sample_rate", e.sample_rate},
              {"frequency", e.frequency},
              {"amplitude", e.amplitude},
              {"static_position", e.static_position},
              {"waveform", e.waveform},
              {"periods", e.periods},
              {"group", e.group},
              {"drop_mass", e.drop_mass},
              {"impact_velocity", e.impact_velocity},
              {"extra", e.extra_attributes},
              {"channels", channels},
              {"raw", raw},
              {"sequence", d.sequence},
              {"status", d.status}}
      .dump();
}

std::vector<std::byte> BlockRecord(const SampleBlock& b) {
  const std::size_t n = b.size();
  std::size_t payload = 12 + n * (8 + 8 * b.values.size() + 4 * b.counts.size());
  if (!b.sequence.empty()) payload += 8 * n;
  if (!b.status.empty()) payload += 4 * n;
  std::vector<std::byte> out;
  out.reserve(payload + kRecordOverhead);
  Put(out, static_cast<std::uint32_t>(payload));
  Put(out, static_cast<std::uint16_t>(RecordType::kBlock));
  Put(out, std::uint16_t{0});
  Put(out, static_cast<std::uint32_t>(n));
  Put(out, static_cast<std::uint16_t>(b.values.size()));
  Put(out, static_cast<std::uint16_t>(b.counts.size()));
  Put(out, static_cast<std::uint8_t>(!b.sequence.empty()));
  Put(out, static_cast<std::uint8_t>(!b.status.empty()));
  Put(out, std::uint16_t{0});
  PutArray(out, b.monotonic_ns);
  for (const auto& v : b.values) PutArray(out, v);
  for (const auto& c : b.counts) PutArray(out, c);
  PutArray(out, b.sequence);
  PutArray(out, b.status);
  Seal(out);
  return out;
}

std::string EventPayload(std::int64_t monotonic_ns, std::string_view kind, std::string_view text) {
  return json{{"monotonic_ns", monotonic_ns}, {"kind", kind}, {"text", text}}.dump();
}

std::string EndPayload(EndStatus status, long periods) {
  return json{{"status", ToString(status)}, {"periods", periods}}.dump();
}

std::string ClockPayload(std::int64_t monotonic_ns, std::int64_t utc_ns) {
  return json{{"monotonic_ns", monotonic_ns}, {"utc_ns", utc_ns}}.dump();
}

std::string ClosePayload(const std::string& closed_utc) {
  return json{{"closed_utc", closed_utc}}.dump();
}

std::string ResumePayload(std::int64_t monotonic_ns, std::int64_t utc_ns, const std::string& resumed_utc,
                          const std::string& text) {
  return json{{"monotonic_ns", monotonic_ns}, {"utc_ns", utc_ns}, {"resumed_utc", resumed_utc}, {"text", text}}.dump();
}

std::string GroupPayload(const MetadataGroup& group) { return GroupJson(group).dump(); }

std::int64_t MonotonicNowNs() {
  timespec t{};
  clock_gettime(CLOCK_MONOTONIC, &t);
  return std::int64_t{t.tv_sec} * 1'000'000'000 + t.tv_nsec;
}

std::int64_t UtcNowNs() {
  timespec t{};
  clock_gettime(CLOCK_REALTIME, &t);
  return std::int64_t{t.tv_sec} * 1'000'000'000 + t.tv_nsec;
}

std::string Iso8601Ms(std::int64_t utc_ns) {
  const std::int64_t ms = utc_ns >= 0 ? utc_ns / 1'000'000 : (utc_ns - 999'999) / 1'000'000;
  const std::time_t seconds = static_cast<std::time_t>(ms >= 0 ? ms / 1000 : (ms - 999) / 1000);
  std::tm utc{};
  gmtime_r(&seconds, &utc);
  std::array<char, 32> text{};
  const std::size_t n = std::strftime(text.data(), text.size(), "%Y-%m-%dT%H:%M:%S", &utc);
  return fmt::format("{}.{:03}Z", std::string_view(text.data(), n), ms - std::int64_t{seconds} * 1000);
}

}  // namespace journal

namespace {

//! A record whose layout or content the writer cannot have produced (a damaged journal).
class DamagedRecord : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

using journal::RecordType;
using nlohmann::json;

struct ClockPair {
  std::int64_t monotonic_ns;
  std::int64_t utc_ns;
};

struct JournalEvent {
  std::int64_t monotonic_ns;
  std::string kind;
  std::string text;
  std::string experiment;     //!< open at the time, or empty
  std::int64_t first_ns = 0;  //!< that experiment's first sample (when it had one)
  bool has_time = false;
};

// An experiment as the journal builds it up.
struct Building {
  ExperimentDescriptor descriptor;
  std::vector<std::int64_t> monotonic_ns;
  std::vector<std::vector<double>> values;
  std::vector<std::vector<double>> counts;
  std::vector<double> sequence;
  std::vector<double> status;
  bool ended = false;
  EndStatus end = EndStatus::kAborted;
  long periods = 0;
};

ExperimentKind KindFromText(const std::string& text) {
  if (text == "periodic") return ExperimentKind::kPeriodic;
  if (text == "drop") return ExperimentKind::kDrop;
  if (text == "static") return ExperimentKind::kStatic;
  if (text == "record") return ExperimentKind::kRecord;
  throw DamagedRecord("unknown experiment kind '" + text + "'");
}

EndStatus EndFromText(const std::string& text) {
  if (text == "complete") return EndStatus::kComplete;
  if (text == "not-steady") return EndStatus::kNotSteady;
  if (text == "aborted") return EndStatus::kAborted;
  throw DamagedRecord("unknown end status '" + text + "'");
}

// A number the writer may have stored as null (JSON has no NaN or Inf).
double Number(const json& j, const char* key) {
  const json& v = j.at(key);
  return v.is_null() ? std::nan("") : v.get<double>();
}

ExperimentDescriptor DescriptorFromJson(const json& j) {
  ExperimentDescriptor d;
  Experiment& e = d.header;
  e.label = j.at("label").get<std::string>();
  e.kind = KindFromText(j.at("kind").get<std::string>());
  e.sample_rate = Number(j, "sample_rate");
  e.frequency = Number(j, "frequency");
  e.amplitude = Number(j, "amplitude");
  e.static_position = Number(j, "static_position");
  e.waveform = j.at("waveform").get<std::string>();
  e.periods = j.at("periods").get<long>();
  e.group = j.at("group").get<std::string>();
  e.drop_mass = Number(j, "drop_mass");
  e.impact_velocity = Number(j, "impact_velocity");
  e.extra_attributes = j.at("extra").get<std::map<std::string, std::string>>();
  for (const json& c : j.at("channels")) {
    e.channels.push_back({c.at("name").get<std::string>(), c.at("units").get<std::string>(),
                          c.at("reference").get<std::string>(), {}});
  }
  for (const json& r : j.at("raw")) {
    d.raw.push_back({r.at("channel").get<std::string>(),
                     {Number(r, "gain"), Number(r, "offset"), Number(r, "range_min"), Number(r, "range_max")}});
  }
  d.sequence = j.at("sequence").get<bool>();
  d.status = j.at("status").get<bool>();
  return d;
}

// Reads records from a journal file one at a time.
class JournalReader {
 public:
  explicit JournalReader(const std::string& path) : path_(path), in_(path, std::ios::binary) {
    namespace fs = std::filesystem;
    std::error_code error;
    if (!fs::exists(path, error)) throw RecorderError(fmt::format("{}: no such file", path));
    if (fs::is_directory(path, error)) {
      throw RecorderError(fmt::format("{}: is a directory, not a recording journal", path));
    }
    if (!in_) throw RecorderError(fmt::format("{}: cannot open: {}", path, std::strerror(errno)));
    size_ = fs::file_size(path, error);
    std::array<char, journal::kHeaderBytes> header{};
    in_.read(header.data(), header.size());
    const auto got = static_cast<std::size_t>(in_.gcount());
    if (got < journal::kHeaderBytes && std::memcmp(header.data(), journal::kMagic, std::min<std::size_t>(got, 8)) == 0) {
      // Created, then cut before its header was whole (a crash inside Open).
      throw RecorderError(fmt::format("{}: journal header cut off ({} of {} bytes): nothing to recover", path, got,
                                      journal::kHeaderBytes));
    }
    if (got < 8 || std::memcmp(header.data(), journal::kMagic, 8) != 0) {
      static constexpr char kHdf5[8] = {'\x89', 'H', 'D', 'F', '\r', '\n', '\x1a', '\n'};
      if (static_cast<std::size_t>(in_.gcount()) >= 8 && std::memcmp(header.data(), kHdf5, 8) == 0) {
        throw RecorderError(fmt::format(
            "{}: is an HDF5 file, not a recording journal: nothing to recover (`strut info` checks it)",
            path));
      }
      throw RecorderError(fmt::format("{}: not a strut recording journal", path));
    }
    std::uint32_t version = 0;
    std::memcpy(&version, header.data() + 8, sizeof version);
    if (version != journal::kVersion) {
      throw RecorderError(fmt::format("{}: journal version {} (this strut reads version {})", path,
                                      version, journal::kVersion));
    }
    offset_ = journal::kHeaderBytes;
  }

  //! The next intact record, or false at the end or at a torn or damaged record.
  bool Next(RecordType& type, std::vector<std::byte>& payload) {
    std::array<std::byte, 8> prefix{};
    if (!Read(prefix.data(), prefix.size())) return false;
    std::uint32_t size = 0;
    std::uint16_t raw_type = 0;
    std::memcpy(&size, prefix.data(), 4);
    std::memcpy(&raw_type, prefix.data() + 4, 2);
    if (size > journal::kMaxPayload || size + journal::kRecordOverhead > size_ - offset_) {
      problem_ = fmt::format("record at byte {} runs past the end of the file (cut off)", offset_);
      return false;
    }
    payload.resize(size);
    std::uint32_t crc = 0;
    if (!Read(payload.data(), size) || !Read(reinterpret_cast<std::byte*>(&crc), 4)) return false;
    std::uint32_t expected = journal::Crc32(prefix);
    expected = journal::Crc32(payload, expected);
    if (crc != expected) {
      problem_ = fmt::format("record at byte {} fails its checksum (torn or damaged)", offset_);
      return false;
    }
    type = static_cast<RecordType>(raw_type);
    offset_ += size + journal::kRecordOverhead;
    return true;
  }

  std::uint64_t offset() const { return offset_; }
  std::uint64_t size() const { return size_; }
  const std::string& problem() const { return problem_; }

 private:
  bool Read(std::byte* out, std::size_t n) {
    in_.read(reinterpret_cast<char*>(out), static_cast<std::streamsize>(n));
    if (static_cast<std::size_t>(in_.gcount()) == n) return true;
    if (problem_.empty()) problem_ = fmt::format("record at byte {} is cut off", offset_);
    return false;
  }

  std::string path_;
  std::ifstream in_;
  std::uint64_t size_ = 0;
  std::uint64_t offset_ = 0;
  std::string problem_;
};

template <typename T>
const std::byte* Take(const std::byte* p, const std::byte* end, std::size_t n, std::vector<T>& out) {
  if (static_cast<std::size_t>(end - p) < n * sizeof(T)) throw DamagedRecord("block shorter than its counts");
  const std::size_t old = out.size();
  out.resize(old + n);
  std::memcpy(out.data() + old, p, n * sizeof(T));
  return p + n * sizeof(T);
}

// Appends integers as doubles (counts, sequence and status are stored as float64 channels).
template <typename T>
const std::byte* TakeAsDouble(const std::byte* p, const std::byte* end, std::size_t n,
                              std::vector<double>& out) {
  if (static_cast<std::size_t>(end - p) < n * sizeof(T)) throw DamagedRecord("block shorter than its counts");
  for (std::size_t i = 0; i < n; ++i, p += sizeof(T)) {
    T v;
    std::memcpy(&v, p, sizeof(T));
    out.push_back(static_cast<double>(v));
  }
  return p;
}

void AppendBlock(Building& b, std::span<const std::byte> payload) {
  if (payload.size() < 12) throw DamagedRecord("block header cut off");
  std::uint32_t n = 0;
  std::uint16_t values = 0, counts = 0;
  std::uint8_t sequence = 0, status = 0;
  std::memcpy(&n, payload.data(), 4);
  std::memcpy(&values, payload.data() + 4, 2);
  std::memcpy(&counts, payload.data() + 6, 2);
  std::memcpy(&sequence, payload.data() + 8, 1);
  std::memcpy(&status, payload.data() + 9, 1);
  if (values != b.values.size() || counts != b.counts.size() ||
      (sequence != 0) != b.descriptor.sequence || (status != 0) != b.descriptor.status) {
    throw DamagedRecord("block does not match its experiment's channels");
  }
  // Checked before anything is copied, so a bad block leaves the experiment as it was.
  const std::size_t expected = 12 + std::size_t{n} * (8 + 8 * values + 4 * counts +
                                                     (sequence ? 8 : 0) + (status ? 4 : 0));
  if (payload.size() != expected) throw DamagedRecord("block size does not match its counts");
  const std::byte* p = payload.data() + 12;
  const std::byte* end = payload.data() + payload.size();
  p = Take(p, end, n, b.monotonic_ns);
  for (auto& v : b.values) p = Take(p, end, n, v);
  for (auto& c : b.counts) p = TakeAsDouble<std::int32_t>(p, end, n, c);
  if (sequence) p = TakeAsDouble<std::uint64_t>(p, end, n, b.sequence);
  if (status) p = TakeAsDouble<std::uint32_t>(p, end, n, b.status);
  if (p != end) throw DamagedRecord("block longer than its counts");
}

// UTC of a monotonic time from the latest clock pair before it (else the first one).
std::int64_t UtcOf(const std::vector<ClockPair>& clock, std::int64_t monotonic_ns) {
  const ClockPair* best = &clock.front();
  for (const ClockPair& c : clock) {
    if (c.monotonic_ns <= monotonic_ns) best = &c;
  }
  return best->utc_ns + (monotonic_ns - best->monotonic_ns);
}

std::string GroupName(std::size_t index) { return fmt::format("{:06}", index); }

// Builds the session from what the journal held.
class Assembler {
 public:
  explicit Assembler(std::string path) : path_(std::move(path)) {}

  void Apply(RecordType type, std::span<const std::byte> payload) {
    if (type == RecordType::kBlock) {
      if (open_ == nullptr) throw DamagedRecord("samples outside an experiment");
      AppendBlock(*open_, payload);
      return;
    }
    const json j = json::parse(payload.begin(), payload.end());
    switch (type) {
      case RecordType::kOpen: {
        session_.created_utc = j.at("created_utc").get<std::string>();
        session_.damper_serial = j.at("damper_serial").get<std::string>();
        session_.rig = j.at("rig").get<std::string>();
        session_.profile = j.at("profile").get<std::string>();
        operator_ = j.at("operator").get<std::string>();
        software_version_ = j.at("software_version").get<std::string>();
        matrix_ = j.at("matrix").get<std::string>();
        limits_ = j.at("limits").get<std::map<std::string, double>>();
        for (const json& g : j.at("groups")) session_.metadata.push_back(journal::GroupFromJson(g));
        clock_.push_back({j.at("monotonic_ns").get<std::int64_t>(), j.at("utc_ns").get<std::int64_t>()});
        opened_ = true;
        break;
      }
      case RecordType::kBegin: {
        if (open_ != nullptr) throw DamagedRecord("an experiment begins inside another");
        Building& b = experiments_.emplace_back();
        b.descriptor = DescriptorFromJson(j);
        b.values.resize(b.descriptor.header.channels.size());
        b.counts.resize(b.descriptor.raw.size());
        open_ = &b;
        break;
      }
      case RecordType::kEvent: {
        JournalEvent e{j.at("monotonic_ns").get<std::int64_t>(), j.at("kind").get<std::string>(),
                       j.at("text").get<std::string>(), {}};
        if (open_ != nullptr) {
          e.experiment = open_->descriptor.header.label;
          if (!open_->monotonic_ns.empty()) {
            e.first_ns = open_->monotonic_ns.front();
            e.has_time = true;
          }
        }
        events_.push_back(std::move(e));
        break;
      }
      case RecordType::kEnd: {
        if (open_ == nullptr) throw DamagedRecord("an experiment ends that did not begin");
        open_->ended = true;
        open_->end = EndFromText(j.at("status").get<std::string>());
        open_->periods = j.at("periods").get<long>();
        open_ = nullptr;
        break;
      }
      case RecordType::kClock:
        clock_.push_back({j.at("monotonic_ns").get<std::int64_t>(), j.at("utc_ns").get<std::int64_t>()});
        break;
      case RecordType::kClose:
        closed_utc_ = j.at("closed_utc").get<std::string>();
        closed_ = true;
        break;
      case RecordType::kResume: {
        // A new process goes on recording: its monotonic clock may be another boot's, so the
        // pair it brings maps its times to UTC from here on.
        if (open_ != nullptr) throw DamagedRecord("a resume inside an experiment");
        const std::int64_t t = j.at("monotonic_ns").get<std::int64_t>();
        clock_.push_back({t, j.at("utc_ns").get<std::int64_t>()});
        events_.push_back({t, "resumed", j.at("text").get<std::string>(), {}});
        closed_ = false;
        break;
      }
      case RecordType::kGroup:
        MergeGroup(journal::GroupFromJson(j));
        break;
      default:
        throw DamagedRecord(fmt::format("unknown record type {}", static_cast<int>(type)));
    }
  }

  bool opened() const { return opened_; }
  bool closed() const { return closed_; }

  Session Finish(JournalReport& report) {
    report.closed = closed_;
    if (open_ != nullptr) report.in_progress = open_->descriptor.header.label;
    for (Building& b : experiments_) Emit(b, report);
    session_.metadata.push_back(RecordingGroup(report));
    return std::move(session_);
  }

 private:
  // Attributes replace those of the same name; subgroups replace the same-named or are appended.
  void MergeGroup(MetadataGroup group) {
    if (group.name == "experiments" || group.name == "recording" || group.name.empty())
      throw DamagedRecord("metadata group '" + group.name + "' is reserved");
    auto it = std::find_if(session_.metadata.begin(), session_.metadata.end(),
                           [&](const MetadataGroup& g) { return g.name == group.name; });
    if (it == session_.metadata.end()) {
      session_.metadata.push_back(std::move(group));
      return;
    }
    for (auto& [name, value] : group.attributes) it->attributes[name] = std::move(value);
    for (MetadataGroup& sub : group.groups) {
      auto same = std::find_if(it->groups.begin(), it->groups.end(), [&](const MetadataGroup& g) { return g.name == sub.name; });
      if (same != it->groups.end()) {
        *same = std::move(sub);
      } else {
        it->groups.push_back(std::move(sub));
      }
    }
  }

  void Emit(Building& b, JournalReport& report) {
    Experiment e = std::move(b.descriptor.header);
    if (b.monotonic_ns.empty()) {
      report.dropped.push_back(e.label);
      events_.push_back({clock_.back().monotonic_ns, "dropped",
                         fmt::format("experiment '{}' ended before its first sample; not written", e.label),
                         e.label});
      return;
    }
    const long requested = e.periods;
    if (!b.ended) {
      report.aborted.push_back(e.label);
      events_.push_back({b.monotonic_ns.back(), "recovered",
                         fmt::format("experiment '{}' was in progress when the recording was cut "
                                     "off: marked aborted",
                                     e.label),
                         e.label, b.monotonic_ns.front(), true});
    }
    const EndStatus end = b.ended ? b.end : EndStatus::kAborted;
    e.status = end == EndStatus::kAborted ? "aborted" : "complete";
    e.periods = end == EndStatus::kAborted ? 0 : b.periods;
    if (end == EndStatus::kAborted && e.kind == ExperimentKind::kPeriodic && requested > 0) {
      e.extra_attributes["requested_periods"] = std::to_string(requested);
    }
    e.extra_attributes["recording_end"] = std::string(ToString(end));
    const std::int64_t first = b.monotonic_ns.front();
    e.extra_attributes["monotonic_start_ns"] = std::to_string(first);
    e.extra_attributes["utc_start"] = journal::Iso8601Ms(UtcOf(clock_, first));

    e.time.resize(b.monotonic_ns.size());
    // Divided by 1e9 (exact in binary), not multiplied by 1e-9 (not exact): the correctly rounded
    // value, so a constant rate of whole nanoseconds gives exactly i / sample_rate, what other tools
    // write, and a replayed session records its own time axis again bit for bit (docs/replay.md).
    for (std::size_t i = 0; i < e.time.size(); ++i) e.time[i] = static_cast<double>(b.monotonic_ns[i] - first) / 1e9;
    for (std::size_t k = 0; k < e.channels.size(); ++k) e.channels[k].samples = std::move(b.values[k]);
    MetadataGroup calibration{e.label, {}, {}};
    for (std::size_t k = 0; k < b.descriptor.raw.size(); ++k) {
      const RawChannel& r = b.descriptor.raw[k];
      const std::string name = r.channel + "_counts";
      e.channels.push_back({name, "1", "", std::move(b.counts[k])});
      calibration.groups.push_back({r.channel,
                                    {{"gain", r.calibration.gain},
                                     {"offset", r.calibration.offset},
                                     {"range_min", r.calibration.range_min},
                                     {"range_max", r.calibration.range_max},
                                     {"counts_channel", name}},
                                    {}});
    }
    if (!calibration.groups.empty()) calibration_.push_back(std::move(calibration));
    if (b.descriptor.sequence) e.channels.push_back({"sequence", "1", "", std::move(b.sequence)});
    if (b.descriptor.status) e.channels.push_back({"status", "1", "", std::move(b.status)});
    detail::SortChannels(e.channels);
    report.samples += e.time.size();
    session_.experiments.push_back(std::move(e));
  }

  MetadataGroup RecordingGroup(const JournalReport& report) const {
    MetadataGroup r{"recording", {}, {}};
    if (!operator_.empty()) r.attributes["operator"] = operator_;
    r.attributes["software_version"] = software_version_;
    if (!matrix_.empty()) r.attributes["matrix"] = matrix_;
    r.attributes["started_utc"] = session_.created_utc;
    r.attributes["ended"] = std::string(closed_ ? "closed" : "recovered");
    if (closed_) r.attributes["closed_utc"] = closed_utc_;
    if (!closed_) r.attributes["journal_bytes_discarded"] = static_cast<long long>(report.bytes_discarded);
    if (!limits_.empty()) {
      MetadataGroup limits{"limits", {}, {}};
      for (const auto& [name, value] : limits_) limits.attributes[name] = value;
      r.groups.push_back(std::move(limits));
    }
    if (!calibration_.empty()) r.groups.push_back({"calibration", {}, calibration_});
    MetadataGroup events{"events", {}, {}};
    for (const JournalEvent& e : events_) {
      MetadataGroup g{GroupName(events.groups.size()), {}, {}};
      g.attributes["monotonic_ns"] = static_cast<long long>(e.monotonic_ns);
      g.attributes["utc"] = journal::Iso8601Ms(UtcOf(clock_, e.monotonic_ns));
      g.attributes["kind"] = e.kind;
      g.attributes["text"] = e.text;
      if (!e.experiment.empty()) g.attributes["experiment"] = e.experiment;
      if (e.has_time) g.attributes["time"] = static_cast<double>(e.monotonic_ns - e.first_ns) / 1e9;
      events.groups.push_back(std::move(g));
    }
    if (!events.groups.empty()) r.groups.push_back(std::move(events));
    MetadataGroup clock{"clock", {}, {}};
    for (const ClockPair& c : clock_) {
      clock.groups.push_back({GroupName(clock.groups.size()),
                              {{"monotonic_ns", static_cast<long long>(c.monotonic_ns)},
                               {"utc_ns", static_cast<long long>(c.utc_ns)},
                               {"utc", journal::Iso8601Ms(c.utc_ns)}},
                              {}});
    }
    r.groups.push_back(std::move(clock));
    return r;
  }

  std::string path_;
  Session session_;
  std::string operator_, software_version_, matrix_, closed_utc_;
  std::map<std::string, double> limits_;
  std::vector<ClockPair> clock_;
  std::vector<JournalEvent> events_;
  std::vector<MetadataGroup> calibration_;
  std::deque<Building> experiments_;  // deque: open_ stays valid as experiments are added
  Building* open_ = nullptr;
  bool opened_ = false;
  bool closed_ = false;
};

}  // namespace

Session ReadJournal(const std::string& journal_path, JournalReport* report_out) {
  JournalReport report;
  JournalReader reader(journal_path);
  Assembler assembler(journal_path);
  RecordType type{};
  std::vector<std::byte> payload;
  std::string problem;
  std::uint64_t good = reader.offset();
  while (reader.Next(type, payload)) {
    if (!assembler.opened() && type != RecordType::kOpen) {
      problem = fmt::format("record at byte {} comes before the recording's header", good);
      break;
    }
    try {
      assembler.Apply(type, payload);
    } catch (const nlohmann::json::exception& e) {  // a damaged record's JSON
      problem = fmt::format("record at byte {} is damaged ({})", good, e.what());
      break;
    } catch (const DamagedRecord& e) {
      problem = fmt::format("record at byte {} is damaged ({})", good, e.what());
      break;
    }
    good = reader.offset();
    ++report.records;
  }
  if (problem.empty()) problem = reader.problem();
  if (!assembler.opened()) {
    throw RecorderError(fmt::format("{}: the recording's header record is {}: nothing to recover",
                                    journal_path, problem.empty() ? "missing" : "cut off or damaged"));
  }
  report.bytes_read = good;
  report.bytes_discarded = reader.size() - good;
  if (report.bytes_discarded > 0) {
    spdlog::warn("{}: {}; the last {} bytes are discarded", journal_path, problem,
                 report.bytes_discarded);
  }
  Session session = assembler.Finish(report);
  session.source_path = journal_path;
  if (report_out != nullptr) *report_out = report;
  return session;
}

JournalReport RecoverJournal(const std::string& journal_path, const std::string& session_path,
                             bool force, const WriteOptions& options) {
  namespace fs = std::filesystem;
  std::error_code error;
  if (fs::exists(session_path, error) && fs::equivalent(journal_path, session_path, error)) {
    throw RecorderError(fmt::format("{}: the output is the journal itself; name another file", session_path));
  }
  if (fs::exists(session_path, error) && !force) {
    throw RecorderError(fmt::format("{}: exists; not overwritten (use --force)", session_path));
  }
  JournalReport report;
  Session session = ReadJournal(journal_path, &report);
  session.source_path.clear();
  WriteSession(session_path, session, options);
  return report;
}

}  // namespace strut::daq
