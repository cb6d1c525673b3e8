// Session files on the HDF5 C API: a tolerant reader (any writer: strut, h5py, MATLAB) and a
// crash-safe writer of the contract format.
#include <hdf5.h>
#include <spdlog/fmt/fmt.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <charconv>
#include <cerrno>
#include <climits>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <exception>
#include <filesystem>
#include <fstream>
#include <new>
#include <optional>
#include <stdexcept>

#include "hdf5_handle.h"
#include "strut/daq/atomic_file.h"
#include "session_check.h"
#include "strut/daq/session.h"

namespace strut::daq {

namespace hdf5 {

std::string TakeErrorMessage() {
  std::string message;
  // Walking upward starts at the most specific error ("truncated file: eof = ...").
  H5E_walk2_t first = [](unsigned, const H5E_error2_t* error, void* data) -> herr_t {
    auto* out = static_cast<std::string*>(data);
    if (!out->empty() || error == nullptr) return 0;
    if (error->desc != nullptr && error->desc[0] != '\0') {
      *out = error->desc;
    } else if (error->func_name != nullptr) {
      *out = std::string(error->func_name) + "() failed";
    }
    return 0;
  };
  H5Ewalk2(H5E_DEFAULT, H5E_WALK_UPWARD, first, &message);
  H5Eclear2(H5E_DEFAULT);
  return message.empty() ? "unknown HDF5 error" : message;
}

}  // namespace hdf5

namespace {

using detail::AttributeItem;
using detail::ChannelAttributeItem;
using detail::ChannelItem;
using detail::DefectList;
using detail::kTimeItem;
using detail::kTimeUnitsItem;

constexpr const char* kFormatName = "damper-session";
// Automatic chunk length: 16384 float64 samples = 128 KiB, well inside HDF5's 1 MiB chunk cache.
constexpr hsize_t kAutoChunkSamples = 16384;

std::string DescribeClass(H5T_class_t type_class) {
  switch (type_class) {
    case H5T_INTEGER:
      return "an integer";
    case H5T_FLOAT:
      return "a floating-point number";
    case H5T_STRING:
      return "a string";
    case H5T_BITFIELD:
      return "a bitfield";
    case H5T_OPAQUE:
      return "opaque data";
    case H5T_COMPOUND:
      return "a compound value";
    case H5T_REFERENCE:
      return "a reference";
    case H5T_ENUM:
      return "an enumeration";
    case H5T_VLEN:
      return "a variable-length sequence";
    case H5T_ARRAY:
      return "an array";
    default:
      return "an unknown type";
  }
}

bool IsNumeric(H5T_class_t type_class) {
  return type_class == H5T_INTEGER || type_class == H5T_FLOAT;
}

// Number of values an attribute holds, or nullopt with `error` set.
std::optional<hssize_t> ValueCount(hid_t attribute, std::string& error) {
  hdf5::Dataspace space(H5Aget_space(attribute));
  if (!space) {
    error = "unreadable dataspace: " + hdf5::TakeErrorMessage();
    return std::nullopt;
  }
  if (H5Sget_simple_extent_type(space.get()) == H5S_NULL) {
    error = "has no value (null dataspace)";
    return std::nullopt;
  }
  const hssize_t count = H5Sget_simple_extent_npoints(space.get());
  if (count < 0) {
    error = "unreadable dataspace: " + hdf5::TakeErrorMessage();
    return std::nullopt;
  }
  return count;
}

// Reads a one-element string attribute of string type `type`, fixed- or variable-length.
std::optional<std::string> ReadStringValue(hid_t attribute, hid_t type, std::string& error) {
  const htri_t variable = H5Tis_variable_str(type);
  const H5T_cset_t cset = H5Tget_cset(type);
  hdf5::Datatype memory(H5Tcopy(H5T_C_S1));
  // Same character set in memory as in the file: HDF5 does not convert between ASCII and UTF-8.
  if (variable < 0 || cset < 0 || !memory || H5Tset_cset(memory.get(), cset) < 0) {
    error = "unreadable string type: " + hdf5::TakeErrorMessage();
    return std::nullopt;
  }
  if (variable > 0) {
    hdf5::Dataspace space(H5Aget_space(attribute));
    char* text = nullptr;
    if (!space || H5Tset_size(memory.get(), H5T_VARIABLE) < 0 ||
        H5Aread(attribute, memory.get(), &text) < 0) {
      error = "cannot read: " + hdf5::TakeErrorMessage();
      return std::nullopt;
    }
    std::string value = text != nullptr ? text : "";
#if H5_VERSION_GE(1, 12, 0)
    H5Treclaim(memory.get(), space.get(), H5P_DEFAULT, &text);
#else
    H5Dvlen_reclaim(memory.get(), space.get(), H5P_DEFAULT, &text);
#endif
    return value;
  }
  const std::size_t size = H5Tget_size(type);
  const H5T_str_t pad = H5Tget_strpad(type);
  std::string value(size, '\0');
  if (size == 0 || pad < 0 || H5Tset_size(memory.get(), size) < 0 ||
      H5Tset_strpad(memory.get(), pad) < 0 || H5Aread(attribute, memory.get(), value.data()) < 0) {
    error = "cannot read: " + hdf5::TakeErrorMessage();
    return std::nullopt;
  }
  value.resize(std::min(value.find('\0'), value.size()));
  if (pad == H5T_STR_SPACEPAD) value.erase(value.find_last_not_of(' ') + 1);
  return value;
}

// A single string value; any other type or shape sets `error`.
std::optional<std::string> GetString(hid_t attribute, std::string& error) {
  hdf5::Datatype type(H5Aget_type(attribute));
  if (!type) {
    error = "unreadable type: " + hdf5::TakeErrorMessage();
    return std::nullopt;
  }
  const H5T_class_t type_class = H5Tget_class(type.get());
  if (type_class != H5T_STRING) {
    error = "expected a string, found " + DescribeClass(type_class);
    return std::nullopt;
  }
  const auto count = ValueCount(attribute, error);
  if (!count) return std::nullopt;
  if (*count != 1) {
    error = fmt::format("expected a single string, found {}", *count);
    return std::nullopt;
  }
  return ReadStringValue(attribute, type.get(), error);
}

// A single number of any integer or floating-point type, converted to double.
std::optional<double> GetNumber(hid_t attribute, std::string& error) {
  hdf5::Datatype type(H5Aget_type(attribute));
  if (!type) {
    error = "unreadable type: " + hdf5::TakeErrorMessage();
    return std::nullopt;
  }
  const H5T_class_t type_class = H5Tget_class(type.get());
  if (!IsNumeric(type_class)) {
    std::string ignored;
    const auto text = type_class == H5T_STRING ? GetString(attribute, ignored) : std::nullopt;
    error = text ? fmt::format("expected a number, found a string (\"{}\")", *text)
                 : "expected a number, found " + DescribeClass(type_class);
    return std::nullopt;
  }
  const auto count = ValueCount(attribute, error);
  if (!count) return std::nullopt;
  if (*count != 1) {
    error = fmt::format("expected a single number, found {} values", *count);
    return std::nullopt;
  }
  double value = 0.0;
  if (H5Aread(attribute, H5T_NATIVE_DOUBLE, &value) < 0) {
    error = "cannot read: " + hdf5::TakeErrorMessage();
    return std::nullopt;
  }
  return value;
}

// Any attribute a plain text can represent (strings, numbers, arrays of numbers, enum values),
// for extra_attributes; nullopt for the rest.
std::optional<std::string> GetText(hid_t attribute) {
  std::string error;
  hdf5::Datatype type(H5Aget_type(attribute));
  if (!type) return std::nullopt;
  const H5T_class_t type_class = H5Tget_class(type.get());
  const auto count = ValueCount(attribute, error);
  if (!count || *count < 1) return std::nullopt;
  if (type_class == H5T_STRING) return GetString(attribute, error);
  if (type_class == H5T_INTEGER) {
    std::vector<long long> values(static_cast<std::size_t>(*count));
    if (H5Aread(attribute, H5T_NATIVE_LLONG, values.data()) < 0) return std::nullopt;
    if (values.size() == 1) return std::to_string(values.front());
    return fmt::format("[{}]", fmt::join(values, ", "));
  }
  if (type_class == H5T_FLOAT) {
    std::vector<double> values(static_cast<std::size_t>(*count));
    if (H5Aread(attribute, H5T_NATIVE_DOUBLE, values.data()) < 0) return std::nullopt;
    if (values.size() == 1) return fmt::format("{}", values.front());
    return fmt::format("[{}]", fmt::join(values, ", "));
  }
  if (type_class == H5T_ENUM && *count == 1) {  // h5py writes booleans as an enum
    std::vector<unsigned char> raw(H5Tget_size(type.get()));
    char name[256] = {};
    if (raw.empty() || H5Aread(attribute, type.get(), raw.data()) < 0 ||
        H5Tenum_nameof(type.get(), raw.data(), name, sizeof name) < 0) {
      return std::nullopt;
    }
    return std::string(name);
  }
  return std::nullopt;
}

// A single integer (as long long), floating-point number (as double) or string; nullopt otherwise.
std::optional<AttributeValue> GetValue(hid_t attribute) {
  std::string error;
  hdf5::Datatype type(H5Aget_type(attribute));
  if (!type) return std::nullopt;
  const H5T_class_t type_class = H5Tget_class(type.get());
  const auto count = ValueCount(attribute, error);
  if (!count || *count != 1) return std::nullopt;
  if (type_class == H5T_STRING) {
    auto text = GetString(attribute, error);
    return text ? std::optional<AttributeValue>(std::move(*text)) : std::nullopt;
  }
  if (type_class == H5T_INTEGER) {
    long long value = 0;
    if (H5Aread(attribute, H5T_NATIVE_LLONG, &value) < 0) return std::nullopt;
    return AttributeValue(value);
  }
  if (type_class == H5T_FLOAT) {
    double value = 0.0;
    if (H5Aread(attribute, H5T_NATIVE_DOUBLE, &value) < 0) return std::nullopt;
    return AttributeValue(value);
  }
  return std::nullopt;
}

// Samples of a numeric dataset of shape (N), (N,1) or (1,N); anything else sets `error`.
std::optional<hsize_t> SampleCount(hid_t dataset, std::string& error) {
  hdf5::Datatype type(H5Dget_type(dataset));
  hdf5::Dataspace space(H5Dget_space(dataset));
  if (!type || !space) {
    error = "unreadable dataset: " + hdf5::TakeErrorMessage();
    return std::nullopt;
  }
  const H5T_class_t type_class = H5Tget_class(type.get());
  if (!IsNumeric(type_class)) {
    error = "expected numeric samples, found " + DescribeClass(type_class);
    return std::nullopt;
  }
  const H5S_class_t space_class = H5Sget_simple_extent_type(space.get());
  if (space_class == H5S_NULL) {
    error = "not one-dimensional (null dataspace)";
    return std::nullopt;
  }
  if (space_class == H5S_SCALAR) {
    error = "not one-dimensional (a scalar)";
    return std::nullopt;
  }
  const int rank = H5Sget_simple_extent_ndims(space.get());
  if (rank < 1 || rank > H5S_MAX_RANK) {
    error = "unreadable dataspace: " + hdf5::TakeErrorMessage();
    return std::nullopt;
  }
  std::vector<hsize_t> dims(static_cast<std::size_t>(rank));
  H5Sget_simple_extent_dims(space.get(), dims.data(), nullptr);
  // MATLAB writes a vector as (1,N) or (N,1): same samples, same order.
  const bool vector = rank == 1 || (rank == 2 && (dims[0] == 1 || dims[1] == 1));
  if (!vector) {
    error = fmt::format("not one-dimensional (shape {})", fmt::join(dims, " x "));
    return std::nullopt;
  }
  return rank == 1 ? dims[0] : dims[0] * dims[1];
}

std::optional<std::vector<double>> GetSamples(hid_t dataset, std::string& error) {
  const auto count = SampleCount(dataset, error);
  if (!count) return std::nullopt;
  std::vector<double> samples;
  try {
    samples.resize(*count);
  } catch (const std::bad_alloc&) {  // a damaged or absurd extent
    error = fmt::format("cannot hold {} samples in memory", *count);
    return std::nullopt;
  } catch (const std::length_error&) {
    error = fmt::format("cannot hold {} samples in memory", *count);
    return std::nullopt;
  }
  // HDF5 converts float32 and integers to double and runs the decompression filters.
  if (!samples.empty() &&
      H5Dread(dataset, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, samples.data()) < 0) {
    error = "cannot read samples: " + hdf5::TakeErrorMessage();
    return std::nullopt;
  }
  return samples;
}

// The names an HDF5 iteration collects. No exception may cross the C library, so the callback
// keeps whatever it threw (a bad_alloc) and Rethrow() raises it after the iteration.
struct NameCollector {
  std::vector<std::string> names;
  std::exception_ptr error;

  static herr_t Add(const char* name, void* data) {
    auto* self = static_cast<NameCollector*>(data);
    try {
      self->names.emplace_back(name);
      return 0;
    } catch (...) {  // carried across the C library, rethrown by Rethrow()
      self->error = std::current_exception();
      return -1;
    }
  }
  void Rethrow() const {
    if (error) std::rethrow_exception(error);
  }
};

// Names of the attributes of `object`, in name order.
std::vector<std::string> AttributeNames(hid_t object) {
  NameCollector collector;
  hsize_t index = 0;
  H5A_operator2_t collect = [](hid_t, const char* name, const H5A_info_t*, void* data) -> herr_t {
    return NameCollector::Add(name, data);
  };
  H5Aiterate2(object, H5_INDEX_NAME, H5_ITER_INC, &index, collect, &collector);
  collector.Rethrow();
  return std::move(collector.names);
}

// Names of the links in `group`: in creation order when the group records it (strut writes
// /experiments that way, so experiments come back in recording order), else in name order.
std::optional<std::vector<std::string>> LinkNames(hid_t group) {
  H5_index_t order = H5_INDEX_NAME;
  hdf5::PropertyList create(H5Gget_create_plist(group));
  unsigned flags = 0;
  if (create && H5Pget_link_creation_order(create.get(), &flags) >= 0 &&
      (flags & H5P_CRT_ORDER_INDEXED) != 0) {
    order = H5_INDEX_CRT_ORDER;
  }
  NameCollector collector;
  hsize_t index = 0;
  // `auto` fits both the 1.10 (H5L_info_t) and the 1.12 (H5L_info2_t) callback.
  auto collect = [](hid_t, const char* name, const auto*, void* data) -> herr_t { return NameCollector::Add(name, data); };
  const herr_t status = H5Literate(group, order, H5_ITER_INC, &index, collect, &collector);
  collector.Rethrow();
  if (status < 0) return std::nullopt;
  return std::move(collector.names);
}

// Reads from file systems without lock support (some NFS mounts) instead of failing there.
bool AllowUnlockableFileSystems(hid_t access) {
#if H5_VERSION_GE(1, 10, 7)
  return H5Pset_file_locking(access, true, true) >= 0;
#else
  (void)access;
  return true;
#endif
}

H5I_type_t ObjectType(hid_t parent, const std::string& name) {
  hdf5::Object object(H5Oopen(parent, name.c_str(), H5P_DEFAULT));
  return object ? H5Iget_type(object.get()) : H5I_BADID;
}

// Reads a file into a Session, recording every defect instead of stopping at the first.
class Reader {
 public:
  explicit Reader(const std::string& path) : path_(path), defects_(path) {}

  Session Read() {
    CheckReadable();
    hdf5::PropertyList access(H5Pcreate(H5P_FILE_ACCESS));
    if (!access || H5Pset_fclose_degree(access.get(), H5F_CLOSE_STRONG) < 0 ||
        !AllowUnlockableFileSystems(access.get())) {
      throw SessionError(fmt::format("{}: cannot read: {}", path_, hdf5::TakeErrorMessage()));
    }
    hdf5::File file(H5Fopen(path_.c_str(), H5F_ACC_RDONLY, access.get()));
    if (!file) {
      throw SessionError(
          fmt::format("{}: cannot open as HDF5 (truncated, damaged or locked by a writer?): {}",
                      path_, hdf5::TakeErrorMessage()));
    }
    Session session;
    session.source_path = path_;
    ReadRoot(file.get(), session);
    ReadExperiments(file.get(), session);
    ReadMetadata(file.get(), session);
    detail::CheckSession(session, defects_);
    if (!defects_.empty()) throw SessionError(defects_.Joined());
    return session;
  }

 private:
  // The problems that make reading pointless: each one alone is the whole message.
  void CheckReadable() const {
    namespace fs = std::filesystem;
    std::error_code error;
    const fs::file_status status = fs::status(path_, error);
    if (!fs::exists(status)) throw SessionError(fmt::format("{}: no such file", path_));
    if (fs::is_directory(status)) {
      throw SessionError(fmt::format("{}: is a directory, not a session file", path_));
    }
    if (!std::ifstream(path_, std::ios::binary)) {
      throw SessionError(fmt::format("{}: cannot open: {}", path_, std::strerror(errno)));
    }
    if (fs::file_size(path_, error) == 0 && !error) {
      throw SessionError(fmt::format("{}: empty file, not an HDF5 file", path_));
    }
    const htri_t is_hdf5 = H5Fis_hdf5(path_.c_str());
    if (is_hdf5 == 0) throw SessionError(fmt::format("{}: not an HDF5 file", path_));
    if (is_hdf5 < 0) {
      throw SessionError(fmt::format("{}: cannot read: {}", path_, hdf5::TakeErrorMessage()));
    }
  }

  // The attribute, an empty handle when it is missing (reported when `required`).
  hdf5::Attribute Open(hid_t object, const char* name, std::string_view experiment,
                       std::string_view item, bool required) {
    const htri_t exists = H5Aexists(object, name);
    if (exists < 0) {
      defects_.Add(experiment, item, "unreadable: " + hdf5::TakeErrorMessage());
      return {};
    }
    if (exists == 0) {
      if (required) defects_.Add(experiment, item, "missing");
      return {};
    }
    hdf5::Attribute attribute(H5Aopen(object, name, H5P_DEFAULT));
    if (!attribute) defects_.Add(experiment, item, "cannot open: " + hdf5::TakeErrorMessage());
    return attribute;
  }

  std::optional<std::string> String(hid_t object, const char* name, std::string_view experiment,
                                    std::string_view item, bool required = true) {
    const hdf5::Attribute attribute = Open(object, name, experiment, item, required);
    if (!attribute) return std::nullopt;
    std::string error;
    auto value = GetString(attribute.get(), error);
    if (!value) defects_.Add(experiment, item, error);
    return value;
  }

  std::optional<double> Number(hid_t object, const char* name, std::string_view experiment,
                               bool required = true) {
    const std::string item = AttributeItem(name);
    const hdf5::Attribute attribute = Open(object, name, experiment, item, required);
    if (!attribute) return std::nullopt;
    std::string error;
    const auto value = GetNumber(attribute.get(), error);
    if (!value) defects_.Add(experiment, item, error);
    return value;
  }

  // A number that must be integral (MATLAB stores 5 as the double 5.0, which is fine).
  std::optional<long> Whole(hid_t object, const char* name, std::string_view experiment) {
    const auto value = Number(object, name, experiment);
    if (!value) return std::nullopt;
    if (!(std::isfinite(*value) && std::floor(*value) == *value && std::abs(*value) < 1e15)) {
      defects_.Add(experiment, AttributeItem(name),
                   fmt::format("must be a whole number, found {}", *value));
      return std::nullopt;
    }
    return static_cast<long>(*value);
  }

  void ReadRoot(hid_t file, Session& session) {
    const std::string format_item = AttributeItem("format");
    if (const auto format = String(file, "format", "", format_item)) {
      if (*format != kFormatName) {
        defects_.Add("", format_item, fmt::format("'{}', expected \"{}\"", *format, kFormatName));
      }
    }
    if (const auto version = Whole(file, "format_version", "")) {
      session.format_version = static_cast<int>(std::clamp<long>(*version, INT_MIN, INT_MAX));
    }
    if (auto text = String(file, "created_utc", "", AttributeItem("created_utc"))) {
      session.created_utc = std::move(*text);
    }
    if (auto text = String(file, "damper_serial", "", AttributeItem("damper_serial"))) {
      session.damper_serial = std::move(*text);
    }
    if (auto text = String(file, "rig", "", AttributeItem("rig"))) session.rig = std::move(*text);
    // strut's extension (docs/session-files.md): absent means the contract's damper profile.
    if (auto text = String(file, "profile", "", AttributeItem("profile"), false)) {
      session.profile = std::move(*text);
    }
    generic_ = session.profile == kGenericProfile;
  }

  void ReadExperiments(hid_t file, Session& session) {
    const htri_t exists = H5Lexists(file, "experiments", H5P_DEFAULT);
    if (exists <= 0) {
      defects_.Add("", detail::kExperimentsItem, "missing");
      return;
    }
    if (ObjectType(file, "experiments") != H5I_GROUP) {
      defects_.Add("", detail::kExperimentsItem, "is not a group");
      return;
    }
    hdf5::Group experiments(H5Gopen2(file, "experiments", H5P_DEFAULT));
    const auto labels = experiments ? LinkNames(experiments.get()) : std::nullopt;
    if (!labels) {
      defects_.Add("", detail::kExperimentsItem, "cannot list: " + hdf5::TakeErrorMessage());
      return;
    }
    for (const std::string& label : *labels) {
      const H5I_type_t type = ObjectType(experiments.get(), label);
      if (type == H5I_BADID) {
        defects_.Add(label, "group", "cannot open: " + hdf5::TakeErrorMessage());
      } else if (type == H5I_GROUP) {
        session.experiments.push_back(ReadExperiment(experiments.get(), label));
      } else {
        spdlog::debug("{}: /experiments/{} is not a group, ignored", path_, label);
      }
    }
  }

  // Extra root groups (strut's metadata, e.g. /truth): their attributes and subgroups; datasets
  // in them and attributes without a single number or text are ignored (logged at debug level).
  void ReadMetadata(hid_t file, Session& session) {
    const auto names = LinkNames(file);
    if (!names) return;
    for (const std::string& name : *names) {
      if (name == "experiments" || ObjectType(file, name) != H5I_GROUP) continue;
      session.metadata.push_back(ReadMetadataGroup(file, name, "/" + name));
    }
  }

  MetadataGroup ReadMetadataGroup(hid_t parent, const std::string& name, const std::string& path) {
    MetadataGroup m;
    m.name = name;
    hdf5::Group group(H5Gopen2(parent, name.c_str(), H5P_DEFAULT));
    if (!group) {
      spdlog::debug("{}: group {} cannot be opened, ignored", path_, path);
      return m;
    }
    for (const std::string& attribute_name : AttributeNames(group.get())) {
      hdf5::Attribute attribute(H5Aopen(group.get(), attribute_name.c_str(), H5P_DEFAULT));
      if (auto value = attribute ? GetValue(attribute.get()) : std::nullopt) {
        m.attributes.emplace(attribute_name, std::move(*value));
      } else {
        spdlog::debug("{}: {}: attribute '{}' is not a single number or text, ignored", path_, path,
                      attribute_name);
      }
    }
    if (const auto links = LinkNames(group.get())) {
      for (const std::string& link : *links) {
        if (ObjectType(group.get(), link) == H5I_GROUP) {
          m.groups.push_back(ReadMetadataGroup(group.get(), link, path + "/" + link));
        } else {
          spdlog::debug("{}: {}/{} is not a group, ignored", path_, path, link);
        }
      }
    }
    return m;
  }

  Experiment ReadExperiment(hid_t parent, const std::string& label) {
    Experiment e;
    e.label = label;
    hdf5::Group group(H5Gopen2(parent, label.c_str(), H5P_DEFAULT));
    if (!group) {
      defects_.Add(label, "group", "cannot open: " + hdf5::TakeErrorMessage());
      return e;
    }
    const hid_t g = group.get();
    const std::string kind_item = AttributeItem("kind");
    bool kind_known = false;
    if (const auto kind = String(g, "kind", label, kind_item)) {
      kind_known = true;
      if (*kind == "periodic") {
        e.kind = ExperimentKind::kPeriodic;
      } else if (*kind == "drop") {
        e.kind = ExperimentKind::kDrop;
      } else if (*kind == "static") {
        e.kind = ExperimentKind::kStatic;
      } else if (*kind == "record" && generic_) {
        e.kind = ExperimentKind::kRecord;
      } else {
        kind_known = false;
        defects_.Add(label, kind_item,
                     fmt::format("'{}' is not \"periodic\", \"drop\" or \"static\"{}", *kind,
                                 generic_ ? " or \"record\"" : ""));
      }
    }
    if (auto status = String(g, "status", label, AttributeItem("status"))) e.status = *status;
    e.sample_rate = Number(g, "sample_rate", label).value_or(0.0);
    if (kind_known && e.kind == ExperimentKind::kPeriodic) {
      e.frequency = Number(g, "frequency", label).value_or(0.0);
      e.amplitude = Number(g, "amplitude", label, !generic_).value_or(0.0);
      e.static_position = Number(g, "static_position", label, !generic_).value_or(0.0);
      if (auto waveform = String(g, "waveform", label, AttributeItem("waveform"))) {
        e.waveform = *waveform;
      }
      e.periods = Whole(g, "periods", label).value_or(0);
      if (auto name = String(g, "group", label, AttributeItem("group"), false)) e.group = *name;
    } else if (kind_known && e.kind == ExperimentKind::kDrop) {
      e.drop_mass = Number(g, "drop_mass", label).value_or(0.0);
      e.impact_velocity = Number(g, "impact_velocity", label).value_or(0.0);
    }
    // With an unknown kind only the common attributes are the contract's (the file is
    // rejected anyway, this just keeps the other checks quiet).
    const ExperimentKind attribute_kind = kind_known ? e.kind : ExperimentKind::kStatic;
    for (const std::string& name : AttributeNames(g)) {
      if (detail::IsContractAttribute(attribute_kind, name)) continue;
      hdf5::Attribute attribute(H5Aopen(g, name.c_str(), H5P_DEFAULT));
      if (auto text = attribute ? GetText(attribute.get()) : std::nullopt) {
        e.extra_attributes.emplace(name, std::move(*text));
      } else {
        spdlog::debug("{}: experiment '{}': attribute '{}' has no text form, ignored", path_, label,
                      name);
      }
    }
    ReadDatasets(g, e);
    return e;
  }

  // The dataset, or an empty handle when missing or not a dataset (reported when required).
  hdf5::Dataset OpenDataset(hid_t group, const std::string& name, std::string_view experiment,
                            std::string_view item) {
    const htri_t exists = H5Lexists(group, name.c_str(), H5P_DEFAULT);
    if (exists <= 0) {
      defects_.Add(experiment, item, "missing dataset");
      return {};
    }
    const H5I_type_t type = ObjectType(group, name);
    if (type != H5I_DATASET) {
      defects_.Add(experiment, item,
                   type == H5I_BADID ? "cannot open: " + hdf5::TakeErrorMessage()
                                     : std::string("is not a dataset"));
      return {};
    }
    hdf5::Dataset dataset(H5Dopen2(group, name.c_str(), H5P_DEFAULT));
    if (!dataset) defects_.Add(experiment, item, "cannot open: " + hdf5::TakeErrorMessage());
    return dataset;
  }

  std::vector<double> Samples(hid_t dataset, std::string_view experiment, std::string_view item) {
    std::string error;
    auto samples = GetSamples(dataset, error);
    if (!samples) {
      defects_.Add(experiment, item, error);
      return {};
    }
    return std::move(*samples);
  }

  void ReadDatasets(hid_t group, Experiment& e) {
    const std::string& label = e.label;
    std::optional<std::size_t> length;  // of `time`, when it could be read
    if (const hdf5::Dataset time = OpenDataset(group, "time", label, kTimeItem)) {
      e.time = Samples(time.get(), label, kTimeItem);
      if (!defects_.Has(label, kTimeItem)) length = e.time.size();
      // The contract does not require units on `time`; when present they must be seconds.
      if (const auto units = String(time.get(), "units", label, kTimeUnitsItem, false)) {
        if (*units != "s") {
          defects_.Add(label, kTimeUnitsItem,
                       detail::IsKnownUnit(*units)
                           ? fmt::format("'{}', expected 's'", *units)
                           : fmt::format("unknown units '{}' (expected 's')", *units));
        }
      }
    }

    for (std::string_view standard : detail::kStandardChannels) {
      const std::string name(standard);
      const std::string item = ChannelItem(name);
      // Generic sessions name their own channels: a standard one is read when it is there.
      if (generic_ && H5Lexists(group, name.c_str(), H5P_DEFAULT) <= 0) continue;
      const hdf5::Dataset dataset = OpenDataset(group, name, label, item);
      if (!dataset) continue;
      Channel channel;
      channel.name = name;
      channel.samples = Samples(dataset.get(), label, item);
      if (auto units = String(dataset.get(), "units", label, ChannelAttributeItem(name, "units"))) {
        channel.units = std::move(*units);
      }
      if (name == "pressure") {
        if (auto reference = String(dataset.get(), "reference", label,
                                    ChannelAttributeItem(name, "reference"))) {
          channel.reference = std::move(*reference);
        }
      }
      e.channels.push_back(std::move(channel));
    }

    const auto names = LinkNames(group);
    for (const std::string& name : names.value_or(std::vector<std::string>{})) {
      if (name == "time" || e.find_channel(name) != nullptr ||
          std::find(std::begin(detail::kStandardChannels), std::end(detail::kStandardChannels),
                    name) != std::end(detail::kStandardChannels)) {
        continue;
      }
      if (auto channel = ExtraChannel(group, name, label, length)) {
        e.channels.push_back(std::move(*channel));
      }
    }
    detail::SortChannels(e.channels);
  }

  // A further dataset becomes a channel when it has `units` and as many samples as `time`.
  std::optional<Channel> ExtraChannel(hid_t group, const std::string& name,
                                      std::string_view experiment,
                                      std::optional<std::size_t> length) {
    if (ObjectType(group, name) != H5I_DATASET) return std::nullopt;
    hdf5::Dataset dataset(H5Dopen2(group, name.c_str(), H5P_DEFAULT));
    if (!dataset || H5Aexists(dataset.get(), "units") <= 0) return std::nullopt;
    std::string error;
    const auto count = SampleCount(dataset.get(), error);
    if (!length || !count || *count != *length) {
      spdlog::debug("{}: experiment '{}': dataset '{}' is not a channel ({}), ignored", path_,
                    experiment, name, count ? "different length" : error);
      return std::nullopt;
    }
    Channel channel;
    channel.name = name;
    channel.samples = Samples(dataset.get(), experiment, ChannelItem(name));
    if (auto units =
            String(dataset.get(), "units", experiment, ChannelAttributeItem(name, "units"))) {
      channel.units = std::move(*units);
    }
    return channel;
  }

  std::string path_;
  DefectList defects_;
  bool generic_ = false;  //!< the file's profile is "generic"
};

// The number `text` spells in canonical form: what GetText prints for an int64 or float64
// attribute (so a rewrite reads back the same text); nullopt for any other text ("0042", "1e3",
// " 5", "true"), which therefore stays a string.
std::optional<AttributeValue> CanonicalNumber(const std::string& text) {
  if (text.empty() || text.size() > 40) return std::nullopt;
  const char* begin = text.data();
  const char* end = begin + text.size();
  long long integer = 0;
  if (auto [ptr, ec] = std::from_chars(begin, end, integer); ec == std::errc() && ptr == end) {
    if (std::to_string(integer) == text) return AttributeValue(integer);
    return std::nullopt;
  }
  double value = 0.0;
  if (auto [ptr, ec] = std::from_chars(begin, end, value); ec == std::errc() && ptr == end) {
    if (fmt::format("{}", value) == text) return AttributeValue(value);
  }
  return std::nullopt;
}

// Builds the file in memory (HDF5 core driver) and returns its bytes. HDF5 itself never
// touches the disk when writing: after a failed write or close (disk full) HDF5 1.10 keeps a
// half-closed file that crashes the library at exit, while our own write(2) fails cleanly.
// Every HDF5 call is checked; a failure throws SessionError.
class Writer {
 public:
  Writer(std::string path, const WriteOptions& options)
      : path_(std::move(path)), options_(options) {}

  std::vector<unsigned char> Image(const Session& session) {
    generic_ = session.generic();
    hdf5::PropertyList access(Checked(H5Pcreate(H5P_FILE_ACCESS), "file access properties"));
    Check(H5Pset_fapl_core(access.get(), GrowthIncrement(session), false), "in-memory file");
    hdf5::File file(Checked(H5Fcreate(path_.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, access.get()),
                            "creating the in-memory file"));
    const hid_t root = file.get();
    StringAttribute(root, "format", kFormatName, "root");
    IntegerAttribute(root, "format_version", session.format_version, H5T_STD_I32LE, "root");
    StringAttribute(root, "created_utc", session.created_utc, "root");
    StringAttribute(root, "damper_serial", session.damper_serial, "root");
    StringAttribute(root, "rig", session.rig, "root");
    if (session.profile != kDamperProfile) StringAttribute(root, "profile", session.profile, "root");

    // Record creation order so experiments read back in the order they were recorded.
    hdf5::PropertyList create(Checked(H5Pcreate(H5P_GROUP_CREATE), "group properties"));
    Check(H5Pset_link_creation_order(create.get(), H5P_CRT_ORDER_TRACKED | H5P_CRT_ORDER_INDEXED),
          "group properties");
    hdf5::Group experiments(Checked(
        H5Gcreate2(root, "experiments", H5P_DEFAULT, create.get(), H5P_DEFAULT), "/experiments"));
    for (const Experiment& e : session.experiments) WriteExperiment(experiments.get(), e);
    Check(experiments.Close(), "/experiments");
    for (const MetadataGroup& m : session.metadata) WriteMetadata(root, m, "/" + m.name);

    Check(H5Fflush(root, H5F_SCOPE_GLOBAL), "flushing");
    const ssize_t size = H5Fget_file_image(root, nullptr, 0);
    Check(size, "file image");
    std::vector<unsigned char> image(static_cast<std::size_t>(size));
    Check(H5Fget_file_image(root, image.data(), image.size()), "file image");
    Check(file.Close(), "closing the in-memory file");
    return image;
  }

 private:
  void Check(long long status, std::string_view what) const {
    if (status < 0) {
      throw SessionError(
          fmt::format("{}: cannot write: {}: {}", path_, what, hdf5::TakeErrorMessage()));
    }
  }
  hid_t Checked(hid_t id, std::string_view what) const {
    Check(id, what);
    return id;
  }

  // The in-memory file grows in steps of this: about the uncompressed samples, so a small
  // session needs one allocation and a large one a few.
  static std::size_t GrowthIncrement(const Session& session) {
    std::size_t bytes = 64 * 1024;
    for (const Experiment& e : session.experiments) {
      bytes += (e.channels.size() + 1) * e.time.size() * sizeof(double) + 16 * 1024;
    }
    return std::min<std::size_t>(bytes, 64 * 1024 * 1024);
  }

  void WriteExperiment(hid_t parent, const Experiment& e) {
    const std::string where = fmt::format("experiment '{}'", e.label);
    hdf5::Group group(
        Checked(H5Gcreate2(parent, e.label.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), where));
    const hid_t g = group.get();
    StringAttribute(g, "kind", std::string(ToString(e.kind)), where);
    StringAttribute(g, "status", e.status, where);
    DoubleAttribute(g, "sample_rate", e.sample_rate, where);
    if (e.kind == ExperimentKind::kPeriodic) {
      DoubleAttribute(g, "frequency", e.frequency, where);
      // Generic sessions: amplitude and static position only when they mean something.
      if (!generic_ || e.amplitude != 0.0) DoubleAttribute(g, "amplitude", e.amplitude, where);
      if (!generic_ || e.static_position != 0.0) {
        DoubleAttribute(g, "static_position", e.static_position, where);
      }
      StringAttribute(g, "waveform", e.waveform, where);
      IntegerAttribute(g, "periods", e.periods, H5T_STD_I64LE, where);
      if (!e.group.empty()) StringAttribute(g, "group", e.group, where);
    } else if (e.kind == ExperimentKind::kDrop) {
      DoubleAttribute(g, "drop_mass", e.drop_mass, where);
      DoubleAttribute(g, "impact_velocity", e.impact_velocity, where);
    }
    for (const auto& [name, value] : e.extra_attributes) ExtraAttribute(g, name, value, where);

    Samples(g, "time", e.time, "s", "", where);
    for (const Channel& c : e.channels) Samples(g, c.name, c.samples, c.units, c.reference, where);
    Check(group.Close(), where);
  }

  void WriteMetadata(hid_t parent, const MetadataGroup& m, const std::string& where) {
    hdf5::PropertyList create(Checked(H5Pcreate(H5P_GROUP_CREATE), "group properties"));
    Check(H5Pset_link_creation_order(create.get(), H5P_CRT_ORDER_TRACKED | H5P_CRT_ORDER_INDEXED),
          "group properties");
    hdf5::Group group(
        Checked(H5Gcreate2(parent, m.name.c_str(), H5P_DEFAULT, create.get(), H5P_DEFAULT), where));
    for (const auto& [name, value] : m.attributes) {
      if (const double* d = std::get_if<double>(&value)) {
        DoubleAttribute(group.get(), name, *d, where);
      } else if (const long long* i = std::get_if<long long>(&value)) {
        IntegerAttribute(group.get(), name, *i, H5T_STD_I64LE, where);
      } else {
        StringAttribute(group.get(), name, std::get<std::string>(value), where);
      }
    }
    for (const MetadataGroup& g : m.groups) WriteMetadata(group.get(), g, where + "/" + g.name);
    Check(group.Close(), where);
  }

  // Variable-length UTF-8 strings: h5py returns them as `str` (fixed-length ones come back as
  // `bytes`), MATLAB R2020a+ and HDFView show them as text. ASCII is a subset of UTF-8.
  void StringAttribute(hid_t object, const std::string& name, const std::string& value,
                       std::string_view where) {
    const std::string what = fmt::format("{}: attribute '{}'", where, name);
    hdf5::Datatype type(Checked(H5Tcopy(H5T_C_S1), what));
    Check(H5Tset_size(type.get(), H5T_VARIABLE), what);
    Check(H5Tset_cset(type.get(), H5T_CSET_UTF8), what);
    const char* text = value.c_str();
    WriteAttribute(object, name, type.get(), type.get(), &text, what);
  }

  // An extra experiment attribute: a text that is a number in canonical form (an integer
  // without leading zeros, or a float exactly as the reader prints it back) is stored as int64
  // or float64, so h5py gets numbers for numeric metadata; every other text stays a string.
  // Reading the file back gives the same text either way.
  void ExtraAttribute(hid_t object, const std::string& name, const std::string& value,
                      std::string_view where) {
    if (const auto number = CanonicalNumber(value)) {
      if (const long long* i = std::get_if<long long>(&*number)) {
        IntegerAttribute(object, name, *i, H5T_STD_I64LE, where);
      } else {
        DoubleAttribute(object, name, std::get<double>(*number), where);
      }
      return;
    }
    StringAttribute(object, name, value, where);
  }

  void DoubleAttribute(hid_t object, const std::string& name, double value,
                       std::string_view where) {
    WriteAttribute(object, name, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, &value,
                   fmt::format("{}: attribute '{}'", where, name));
  }

  void IntegerAttribute(hid_t object, const std::string& name, long long value, hid_t file_type,
                        std::string_view where) {
    WriteAttribute(object, name, file_type, H5T_NATIVE_LLONG, &value,
                   fmt::format("{}: attribute '{}'", where, name));
  }

  void WriteAttribute(hid_t object, const std::string& name, hid_t file_type, hid_t memory_type,
                      const void* value, const std::string& what) {
    hdf5::Dataspace scalar(Checked(H5Screate(H5S_SCALAR), what));
    hdf5::Attribute attribute(Checked(
        H5Acreate2(object, name.c_str(), file_type, scalar.get(), H5P_DEFAULT, H5P_DEFAULT), what));
    Check(H5Awrite(attribute.get(), memory_type, value), what);
    Check(attribute.Close(), what);
  }

  void Samples(hid_t group, const std::string& name, const std::vector<double>& samples,
               std::string_view units, std::string_view reference, std::string_view where) {
    const std::string what = fmt::format("{}: dataset '{}'", where, name);
    const hsize_t count = samples.size();
    hdf5::Dataspace space(Checked(H5Screate_simple(1, &count, nullptr), what));
    hdf5::PropertyList create(Checked(H5Pcreate(H5P_DATASET_CREATE), what));
    hsize_t chunk = 0;
    if (options_.chunk_samples > 0) {
      chunk = std::min<hsize_t>(options_.chunk_samples, count);
    } else if (options_.gzip_level > 0) {
      chunk = std::min(kAutoChunkSamples, count);
    }
    if (chunk > 0) {
      Check(H5Pset_chunk(create.get(), 1, &chunk), what);
      if (options_.gzip_level > 0) {
        // Shuffling the bytes of doubles first compresses them noticeably better.
        Check(H5Pset_shuffle(create.get()), what);
        Check(H5Pset_deflate(create.get(), static_cast<unsigned>(options_.gzip_level)), what);
      }
    }
    hdf5::Dataset dataset(Checked(H5Dcreate2(group, name.c_str(), H5T_IEEE_F64LE, space.get(),
                                             H5P_DEFAULT, create.get(), H5P_DEFAULT),
                                  what));
    Check(H5Dwrite(dataset.get(), H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, samples.data()),
          what);
    StringAttribute(dataset.get(), "units", std::string(units), what);
    if (!reference.empty())
      StringAttribute(dataset.get(), "reference", std::string(reference), what);
    Check(dataset.Close(), what);  // writes the last chunks: can fail on a full disk
  }

  std::string path_;
  WriteOptions options_;
  bool generic_ = false;  //!< writing a generic-profile session
};

}  // namespace

Session ReadSession(const std::string& path) {
  const hdf5::ErrorSilencer silence;
  return Reader(path).Read();
}

void WriteSession(const std::string& path, const Session& session, const WriteOptions& options) {
  detail::DefectList defects(session.source_path.empty() ? "<memory>" : session.source_path);
  detail::CheckSession(session, defects);
  if (!defects.empty()) {
    const std::size_t n = defects.messages().size();
    throw SessionError(fmt::format("{}: not written, the session has {} defect{}:\n{}", path, n,
                                   n == 1 ? "" : "s", defects.Joined()));
  }
  if (options.gzip_level < 0 || options.gzip_level > 9) {
    throw SessionError(
        fmt::format("{}: not written: gzip_level {} is outside 0..9", path, options.gzip_level));
  }
  const hdf5::ErrorSilencer silence;
  if (options.gzip_level > 0 && H5Zfilter_avail(H5Z_FILTER_DEFLATE) <= 0) {
    throw SessionError(fmt::format("{}: not written: this HDF5 library has no gzip filter", path));
  }
  const std::vector<unsigned char> image = Writer(path, options).Image(session);
  try {
    WriteFileAtomically(path, std::string_view(reinterpret_cast<const char*>(image.data()), image.size()));
  } catch (const FileWriteError& e) {
    throw SessionError(e.what());
  }
}

}  // namespace strut::daq
