// Measured records (CSV, MAT through libmatio) and their segmentation into generic sessions.
#include "strut/daq/import.h"

#include <fmt/format.h>
#include <matio.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <optional>
#include <set>

namespace strut::daq {
namespace {

std::string Trim(std::string_view text) {
  const auto first = text.find_first_not_of(" \t\r");
  if (first == std::string_view::npos) return {};
  const auto last = text.find_last_not_of(" \t\r");
  return std::string(text.substr(first, last - first + 1));
}

std::string Unquote(std::string text) {
  text = Trim(text);
  if (text.size() >= 2 && (text.front() == '"' || text.front() == '\'') && text.back() == text.front())
    text = text.substr(1, text.size() - 2);
  return text;
}

std::vector<std::string_view> Split(std::string_view line, char delimiter) {
  std::vector<std::string_view> fields;
  std::size_t start = 0;
  for (;;) {
    const std::size_t at = line.find(delimiter, start);
    fields.push_back(line.substr(start, at == std::string_view::npos ? std::string_view::npos : at - start));
    if (at == std::string_view::npos) break;
    start = at + 1;
  }
  return fields;
}

std::optional<double> ParseNumber(std::string_view text) {
  while (!text.empty() && (text.front() == ' ' || text.front() == '\t')) text.remove_prefix(1);
  while (!text.empty() && (text.back() == ' ' || text.back() == '\t' || text.back() == '\r')) text.remove_suffix(1);
  if (!text.empty() && text.front() == '+') text.remove_prefix(1);
  double value = 0.0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (error != std::errc() || end != text.data() + text.size() || text.empty()) return std::nullopt;
  return value;
}

std::string Names(const std::vector<std::string>& names) {
  std::string out;
  for (const auto& n : names) out += (out.empty() ? "" : ", ") + n;
  return out.empty() ? "none" : out;
}

// libmatio reports through a log function; keep its last message for our error text.
thread_local std::string matio_message;
void MatioLog(int level, char* message) {
  if (message) matio_message = message;
  spdlog::debug("libmatio ({}): {}", level, message ? message : "");
}

struct MatCloser {
  void operator()(mat_t* m) const { Mat_Close(m); }
};
struct VarFreer {
  void operator()(matvar_t* v) const { Mat_VarFree(v); }
};

// The real numeric data of a MAT variable as doubles; nullopt for other classes.
std::optional<std::vector<double>> MatDoubles(const matvar_t* v) {
  if (v->isComplex || v->data == nullptr) return std::nullopt;
  std::size_t count = 1;
  for (int d = 0; d < v->rank; ++d) count *= v->dims[d];
  std::vector<double> out(count);
  const auto copy = [&](auto* typed) {
    for (std::size_t i = 0; i < count; ++i) out[i] = static_cast<double>(typed[i]);
  };
  switch (v->class_type) {
    case MAT_C_DOUBLE: copy(static_cast<const double*>(v->data)); break;
    case MAT_C_SINGLE: copy(static_cast<const float*>(v->data)); break;
    case MAT_C_INT8: copy(static_cast<const int8_t*>(v->data)); break;
    case MAT_C_UINT8: copy(static_cast<const uint8_t*>(v->data)); break;
    case MAT_C_INT16: copy(static_cast<const int16_t*>(v->data)); break;
    case MAT_C_UINT16: copy(static_cast<const uint16_t*>(v->data)); break;
    case MAT_C_INT32: copy(static_cast<const int32_t*>(v->data)); break;
    case MAT_C_UINT32: copy(static_cast<const uint32_t*>(v->data)); break;
    case MAT_C_INT64: copy(static_cast<const int64_t*>(v->data)); break;
    case MAT_C_UINT64: copy(static_cast<const uint64_t*>(v->data)); break;
    default: return std::nullopt;
  }
  return out;
}

long ParseLong(std::string_view text, std::string_view what, std::string_view option) {
  const std::string t = Trim(text);
  long value = 0;
  const auto [end, error] = std::from_chars(t.data(), t.data() + t.size(), value);
  if (t.empty() || error != std::errc() || end != t.data() + t.size())
    throw ImportError(fmt::format("{}: {} '{}' is not a whole number", option, what, t));
  return value;
}

}  // namespace

const std::vector<double>& Record::column(std::string_view name) const {
  for (std::size_t i = 0; i < names.size(); ++i)
    if (names[i] == name) return columns[i];
  throw ImportError(fmt::format("{}: no column '{}' (it has: {})", source, name, Names(names)));
}

Record ReadCsvRecord(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw ImportError(fmt::format("{}: no such file", path));
  if (std::filesystem::is_directory(path, ec)) throw ImportError(fmt::format("{}: is a directory", path));
  std::ifstream in(path, std::ios::binary);
  if (!in) throw ImportError(fmt::format("{}: cannot open", path));
  Record record;
  record.source = path;
  std::string line;
  long line_number = 0;
  // Header: the first non-blank line.
  while (std::getline(in, line)) {
    ++line_number;
    if (!Trim(line).empty()) break;
  }
  if (Trim(line).empty()) throw ImportError(fmt::format("{}: empty file (no header line)", path));
  char delimiter = ',';
  for (char d : {',', ';', '\t'})
    if (line.find(d) != std::string::npos) {
      delimiter = d;
      break;
    }
  std::vector<std::string> header;
  for (auto field : Split(line, delimiter)) header.push_back(Unquote(std::string(field)));
  // A trailing delimiter leaves an empty last name: that field is empty on every line.
  std::size_t width = header.size();
  while (width > 0 && header[width - 1].empty()) --width;
  const long header_line = line_number;
  for (std::size_t c = 0; c < width; ++c) {
    if (header[c].empty())
      throw ImportError(fmt::format("{}:{}: column {} has no name in the header", path, header_line, c + 1));
    if (ParseNumber(header[c]))
      throw ImportError(fmt::format("{}:{}: the first line must name the columns, found the number '{}' in column {}",
                                    path, header_line, header[c], c + 1));
    for (std::size_t d = 0; d < c; ++d)
      if (header[d] == header[c])
        throw ImportError(fmt::format("{}:{}: column name '{}' appears twice", path, header_line, header[c]));
  }
  header.resize(width);

  std::vector<std::vector<double>> values(width);
  // Blank fields: a column blank on every line but the first is a constant written once and is
  // dropped; any other blank field is an error (reported at the first one of its column).
  std::vector<long> blank_count(width, 0), first_blank_line(width, 0);
  std::vector<bool> first_row_blank(width, false);
  long rows = 0;
  while (std::getline(in, line)) {
    ++line_number;
    if (Trim(line).empty()) continue;
    const auto fields = Split(line, delimiter);
    std::size_t count = fields.size();
    while (count > width && Trim(fields[count - 1]).empty()) --count;  // trailing delimiter(s)
    if (count != width)
      throw ImportError(fmt::format("{}:{}: {} field{}, the header (line {}) names {} column{}", path, line_number,
                                    count, count == 1 ? "" : "s", header_line, width, width == 1 ? "" : "s"));
    for (std::size_t c = 0; c < width; ++c) {
      if (Trim(fields[c]).empty()) {
        if (rows == 0) first_row_blank[c] = true;
        if (blank_count[c]++ == 0) first_blank_line[c] = line_number;
        values[c].push_back(NAN);
        continue;
      }
      const auto v = ParseNumber(fields[c]);
      if (!v)
        throw ImportError(fmt::format("{}:{}: column {} ('{}'): '{}' is not a number", path, line_number, c + 1,
                                      header[c], Trim(fields[c])));
      values[c].push_back(*v);
    }
    ++rows;
  }
  if (rows == 0) throw ImportError(fmt::format("{}: a header but no data rows", path));
  for (std::size_t c = 0; c < width; ++c) {
    if (blank_count[c] == 0) {
      record.names.push_back(header[c]);
      record.columns.push_back(std::move(values[c]));
    } else if (rows > 1 && !first_row_blank[c] && blank_count[c] == rows - 1) {
      spdlog::debug("{}: column '{}' holds a value in the first row only ({}); not a signal, dropped", path, header[c],
                    values[c].front());
    } else {
      throw ImportError(fmt::format("{}:{}: column {} ('{}') is empty ({} empty field{} in the column)", path,
                                    first_blank_line[c], c + 1, header[c], blank_count[c],
                                    blank_count[c] == 1 ? "" : "s"));
    }
  }
  if (record.names.empty()) throw ImportError(fmt::format("{}: no column holds a signal", path));
  return record;
}

Record ReadMatRecord(const std::string& path, const std::vector<std::string>& variables) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw ImportError(fmt::format("{}: no such file", path));
  if (std::filesystem::is_directory(path, ec)) throw ImportError(fmt::format("{}: is a directory", path));
  static const bool logging = (Mat_LogInitFunc("strut", &MatioLog), true);
  (void)logging;
  matio_message.clear();
  std::unique_ptr<mat_t, MatCloser> mat(Mat_Open(path.c_str(), MAT_ACC_RDONLY));
  if (!mat)
    throw ImportError(fmt::format("{}: not a MATLAB MAT file libmatio can read{}", path,
                                  matio_message.empty() ? "" : " (" + matio_message + ")"));
  Record record;
  record.source = path;
  std::vector<std::string> skipped;
  // Variables in file order.
  std::vector<std::string> names;
  for (;;) {
    std::unique_ptr<matvar_t, VarFreer> info(Mat_VarReadNextInfo(mat.get()));
    if (!info) break;
    if (info->name) names.emplace_back(info->name);
  }
  const auto wanted = [&](const std::string& name) {
    return variables.empty() || std::find(variables.begin(), variables.end(), name) != variables.end();
  };
  for (const std::string& name : variables)
    if (std::find(names.begin(), names.end(), name) == names.end())
      throw ImportError(fmt::format("{}: no variable '{}' (it has: {})", path, name, Names(names)));
  for (const std::string& name : names) {
    if (!wanted(name)) continue;
    matio_message.clear();
    std::unique_ptr<matvar_t, VarFreer> v(Mat_VarRead(mat.get(), name.c_str()));
    if (!v)
      throw ImportError(fmt::format("{}: variable '{}': cannot read{}", path, name,
                                    matio_message.empty() ? "" : " (" + matio_message + ")"));
    const bool vector = v->rank == 2 && (v->dims[0] == 1 || v->dims[1] == 1) && v->dims[0] * v->dims[1] > 1;
    auto data = vector ? MatDoubles(v.get()) : std::nullopt;
    if (!data) {
      const std::string shape = v->rank == 2 ? fmt::format("{}x{}", v->dims[0], v->dims[1]) : fmt::format("rank {}", v->rank);
      if (!variables.empty())
        throw ImportError(fmt::format("{}: variable '{}' is not a real numeric vector ({}{})", path, name, shape,
                                      v->isComplex ? ", complex" : ""));
      skipped.push_back(fmt::format("{} ({})", name, shape));
      continue;
    }
    record.names.push_back(name);
    record.columns.push_back(std::move(*data));
  }
  if (!skipped.empty()) spdlog::debug("{}: not signals, skipped: {}", path, Names(skipped));
  if (record.names.empty()) throw ImportError(fmt::format("{}: no numeric vector in the file", path));
  for (std::size_t i = 1; i < record.columns.size(); ++i)
    if (record.columns[i].size() != record.columns[0].size())
      throw ImportError(fmt::format("{}: variables '{}' ({} samples) and '{}' ({} samples) differ in length", path,
                                    record.names[0], record.columns[0].size(), record.names[i],
                                    record.columns[i].size()));
  return record;
}

Record ReadRecord(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  if (ext == ".mat") return ReadMatRecord(path);
  if (ext == ".csv" || ext == ".txt") return ReadCsvRecord(path);
  throw ImportError(fmt::format("{}: unknown file type '{}' (.csv, .txt or .mat)", path, ext));
}

ColumnMapping ColumnMapping::Parse(std::string_view text) {
  const auto eq = text.find('=');
  if (eq == std::string_view::npos || eq == 0)
    throw ImportError(fmt::format("--column '{}': expected CHANNEL=COLUMN[:UNITS[:SCALE]]", text));
  ColumnMapping m;
  m.channel = Trim(text.substr(0, eq));
  const auto parts = Split(text.substr(eq + 1), ':');
  m.column = Unquote(std::string(parts[0]));
  if (m.column.empty()) throw ImportError(fmt::format("--column '{}': no column named", text));
  m.units = parts.size() > 1 ? Trim(parts[1]) : "1";
  if (parts.size() > 2) {
    const auto scale = ParseNumber(parts[2]);
    if (!scale || !std::isfinite(*scale) || *scale == 0.0)
      throw ImportError(fmt::format("--column '{}': scale '{}' is not a non-zero number", text, parts[2]));
    m.scale = *scale;
  }
  if (parts.size() > 3) throw ImportError(fmt::format("--column '{}': expected CHANNEL=COLUMN[:UNITS[:SCALE]]", text));
  return m;
}

PeriodicSegments PeriodicSegments::Parse(std::string_view text) {
  PeriodicSegments s;
  std::set<std::string> seen;
  for (auto item : Split(text, ',')) {
    const std::string entry = Trim(item);
    const auto eq = entry.find('=');
    if (eq == std::string::npos)
      throw ImportError(fmt::format("--periodic '{}': '{}' is not KEY=VALUE", text, entry));
    const std::string key = Trim(entry.substr(0, eq)), value = Trim(entry.substr(eq + 1));
    seen.insert(key);
    const std::string option = fmt::format("--periodic '{}'", text);
    if (key == "prefix") s.prefix = value;
    else if (key == "start") s.start = ParseLong(value, key, option);
    else if (key == "period") s.period = ParseLong(value, key, option);
    else if (key == "periods") s.periods = ParseLong(value, key, option);
    else if (key == "count") s.count = ParseLong(value, key, option);
    else if (key == "stride") s.stride = ParseLong(value, key, option);
    else if (key == "waveform") s.waveform = value;
    else if (key == "group") s.group = value;
    else
      throw ImportError(fmt::format(
          "{}: unknown key '{}' (prefix, start, period, periods, count, stride, waveform, group)", option, key));
  }
  if (!seen.count("start") || !seen.count("period"))
    throw ImportError(fmt::format("--periodic '{}': start and period are required", text));
  return s;
}

RecordSegment RecordSegment::Parse(std::string_view text) {
  const auto eq = text.find('=');
  const auto colon = text.find(':', eq == std::string_view::npos ? 0 : eq);
  if (eq == std::string_view::npos || eq == 0 || colon == std::string_view::npos)
    throw ImportError(fmt::format("--record '{}': expected LABEL=START:END (0-based, END excluded)", text));
  RecordSegment r;
  r.label = Trim(text.substr(0, eq));
  const std::string option = fmt::format("--record '{}'", text);
  r.start = ParseLong(text.substr(eq + 1, colon - eq - 1), "start", option);
  r.end = ParseLong(text.substr(colon + 1), "end", option);
  return r;
}

ImportSpec ImportSpec::Silverbox() {
  ImportSpec spec;
  spec.columns = {{"u", "V1", "V", 1.0}, {"y", "V2", "V", 1.0}};
  spec.sample_rate = 1e7 / 16384.0;  // 610.3515625 Hz, the generator's clock
  spec.input_channel = "u";
  PeriodicSegments ms;
  ms.prefix = "ms";
  ms.start = 40986;  // after 100 zeros and 400 transient samples
  ms.period = 8192;
  ms.periods = 1;
  ms.count = 10;
  ms.stride = 8692;  // 100 zeros + 400 transient + 8192
  ms.waveform = "multisine";
  spec.periodic = {ms};
  spec.records = {{"zeros", 0, 86}, {"arrow", 86, 40486}};
  spec.serial = "silverbox";
  spec.rig = "SNLS80mV (Wigren & Schoukens 2013)";
  return spec;
}

daq::Session BuildSession(const Record& record, const ImportSpec& spec) {
  const std::string& file = record.source.empty() ? std::string("<record>") : record.source;
  if (!(spec.sample_rate > 0) || !std::isfinite(spec.sample_rate))
    throw ImportError(fmt::format("{}: the sample rate must be a positive number of Hz, not {}", file, spec.sample_rate));
  if (spec.columns.empty()) throw ImportError(fmt::format("{}: no column mapped to a channel", file));
  std::vector<std::pair<const ColumnMapping*, const std::vector<double>*>> sources;
  std::set<std::string> channel_names;
  for (const ColumnMapping& m : spec.columns) {
    if (!channel_names.insert(m.channel).second)
      throw ImportError(fmt::format("{}: channel '{}' is mapped twice", file, m.channel));
    sources.emplace_back(&m, &record.column(m.column));
  }
  if (!spec.input_channel.empty() && !channel_names.count(spec.input_channel))
    throw ImportError(fmt::format("{}: the input channel '{}' is not among the mapped channels", file, spec.input_channel));
  const long rows = static_cast<long>(record.rows());

  daq::Session session;
  session.profile = std::string(daq::kGenericProfile);
  session.created_utc = daq::UtcNowIso8601();
  session.damper_serial = spec.serial;
  session.rig = spec.rig;
  std::set<std::string> labels;
  const auto add = [&](const std::string& label, long start, long end, std::string_view what) {
    if (start < 0 || end <= start || end > rows)
      throw ImportError(fmt::format("{}: {} '{}' needs samples [{}, {}), the file has {} (0-based, end excluded)", file,
                                    what, label, start, end, rows));
    if (!labels.insert(label).second)
      throw ImportError(fmt::format("{}: experiment label '{}' is used twice", file, label));
    daq::Experiment e;
    e.label = label;
    e.sample_rate = spec.sample_rate;
    e.time.resize(end - start);
    for (long i = 0; i < end - start; ++i) e.time[i] = i / spec.sample_rate;
    for (const auto& [m, column] : sources) {
      daq::Channel c;
      c.name = m->channel;
      c.units = m->units;
      c.samples.assign(column->begin() + start, column->begin() + end);
      if (m->scale != 1.0)
        for (double& v : c.samples) v *= m->scale;
      for (long i = 0; i < end - start; ++i)
        if (!std::isfinite(c.samples[i]))
          throw ImportError(fmt::format("{}: column '{}' row {} (0-based) is not finite, inside {} '{}'", file,
                                        m->column, start + i, what, label));
      e.channels.push_back(std::move(c));
    }
    e.extra_attributes["first_sample"] = std::to_string(start);
    if (!spec.input_channel.empty()) e.extra_attributes["excitation"] = spec.input_channel;
    session.experiments.push_back(std::move(e));
    return &session.experiments.back();
  };
  for (const PeriodicSegments& p : spec.periodic) {
    if (p.period < 4 || p.periods < 1 || p.count < 1 || p.stride < 0)
      throw ImportError(fmt::format("{}: periodic segments '{}': period must be >= 4 samples, periods and count >= 1, "
                                    "stride >= 0",
                                    file, p.prefix));
    const long length = p.period * p.periods;
    const long stride = p.stride > 0 ? p.stride : length;
    for (long k = 0; k < p.count; ++k) {
      const long start = p.start + k * stride;
      daq::Experiment* e =
          add(p.count == 1 ? p.prefix : p.prefix + std::to_string(k), start, start + length, "periodic experiment");
      e->kind = daq::ExperimentKind::kPeriodic;
      e->frequency = spec.sample_rate / p.period;
      e->periods = p.periods;
      e->waveform = p.waveform;
      e->group = p.group;
    }
  }
  for (const RecordSegment& r : spec.records) {
    daq::Experiment* e = add(r.label, r.start, r.end, "record");
    e->kind = daq::ExperimentKind::kRecord;
  }
  if (session.experiments.empty())
    throw ImportError(fmt::format("{}: no experiment defined (give --periodic or --record)", file));
  const auto defects = daq::Validate(session);
  if (!defects.empty()) {
    std::string all;
    for (const auto& d : defects) all += "\n" + d;
    throw ImportError(fmt::format("{}: the imported session is not valid:{}", file, all));
  }
  return session;
}

}  // namespace strut::daq
