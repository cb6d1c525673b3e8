// Session files built by hand for the session-file tests and `strut info`'s (on strut_daq and the
// HDF5 C library): one session of each experiment kind, and a file editor that breaks a good file
// in one place with the HDF5 C API, independently of strut's writer.
#pragma once

#include <gtest/gtest.h>
#include <hdf5.h>

#include <algorithm>
#include <cmath>
#include <initializer_list>
#include <numbers>
#include <stdexcept>
#include <string>
#include <vector>

#include "strut/daq/session.h"
#include "test_support.h"

namespace strut::test {

//! n samples times at `sample_rate`, from 0.
inline std::vector<double> TimeAxis(std::size_t n, double sample_rate) {
  std::vector<double> t(n);
  for (std::size_t i = 0; i < n; ++i) t[i] = static_cast<double>(i) / sample_rate;
  return t;
}

//! A channel sampled at `t`: mean + swing sin(2 pi frequency t).
inline daq::Channel MakeChannel(std::string name, std::string units, const std::vector<double>& t, double mean,
                    double swing, double frequency, std::string reference = "") {
  daq::Channel c{std::move(name), std::move(units), std::move(reference), {}};
  for (double ti : t) c.samples.push_back(mean + swing * std::sin(2 * std::numbers::pi * frequency * ti));
  return c;
}

//! An experiment of `kind` with `n` samples at `sample_rate` on its time axis and no channels yet.
inline daq::Experiment MakeExperiment(std::string label, daq::ExperimentKind kind, double sample_rate, std::size_t n) {
  daq::Experiment e;
  e.label = std::move(label);
  e.kind = kind;
  e.sample_rate = sample_rate;
  e.time = TimeAxis(n, sample_rate);
  return e;
}

// Periodic: 200 Hz, 2 Hz, 3 periods = 300 samples, with a further `temperature` channel.
inline daq::Experiment MakePeriodic(std::string label) {
  daq::Experiment e = MakeExperiment(std::move(label), daq::ExperimentKind::kPeriodic, 200, 300);
  e.frequency = 2;
  e.amplitude = 0.01;
  e.static_position = 0.1;
  e.periods = 3;
  e.group = "high";
  e.channels = {MakeChannel("stroke", "m", e.time, 0.1, 0.01, 2),
                MakeChannel("force", "N", e.time, 5000, 2000, 2),
                MakeChannel("pressure", "Pa", e.time, 2e6, 1e5, 2, "absolute"),
                MakeChannel("temperature", "K", e.time, 293.15, 0.5, 0.1)};
  e.extra_attributes = {{"operator", "jd"}, {"shaker", "MTS-1"}};
  return e;
}

//! Drop: 1 kHz, 250 samples, 500 kg at 2.5 m/s, gauge pressure.
inline daq::Experiment MakeDrop(std::string label) {
  daq::Experiment e = MakeExperiment(std::move(label), daq::ExperimentKind::kDrop, 1000, 250);
  e.drop_mass = 500;
  e.impact_velocity = 2.5;
  e.channels = {MakeChannel("stroke", "m", e.time, 0.05, 0.05, 1),
                MakeChannel("force", "N", e.time, 1e4, 1e4, 1),
                MakeChannel("pressure", "Pa", e.time, 1e5, 5e4, 1, "gauge")};
  return e;
}

//! Static, aborted: 10 Hz, 50 samples, absolute pressure.
inline daq::Experiment MakeStatic(std::string label) {
  daq::Experiment e = MakeExperiment(std::move(label), daq::ExperimentKind::kStatic, 10, 50);
  e.status = "aborted";
  e.channels = {MakeChannel("stroke", "m", e.time, 0.2, 0.001, 0.1),
                MakeChannel("force", "N", e.time, 3e4, 10, 0.1),
                MakeChannel("pressure", "Pa", e.time, 3e6, 1e3, 0.1, "absolute")};
  return e;
}

//! A session of MLG-0042 on shaker-2 with one periodic (a), drop (b) and static (c) experiment each.
inline daq::Session MakeSession() {
  daq::Session s;
  s.created_utc = "2026-11-22T05:32:50Z";
  s.damper_serial = "MLG-0042";
  s.rig = "shaker-2";
  s.experiments = {MakePeriodic("a"), MakeDrop("b"), MakeStatic("c")};
  return s;
}

//! MakeSession() written to dir/name; its path.
inline std::string WriteGoodFile(const TempDir& dir, const std::string& name = "session.h5") {
  const std::string path = dir.file(name);
  daq::WriteSession(path, MakeSession());
  return path;
}

//! Every one of `parts` is in `message`.
inline void ExpectMentions(const std::string& message, std::initializer_list<std::string> parts) {
  for (const std::string& part : parts) {
    EXPECT_NE(message.find(part), std::string::npos)
        << "message does not mention \"" << part << "\":\n"
        << message;
  }
}

//! Throws when an HDF5 call of a test failed (a negative status or id).
inline void Require(long long status, const char* what) {
  if (status < 0) throw std::runtime_error(std::string("HDF5 call failed in test: ") + what);
}

// Opens a file for surgery with the HDF5 C API: the defect tests break a good file in one place.
class FileEditor {
 public:
  explicit FileEditor(const std::string& path)
      : file_(H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT)) {
    Require(file_, "H5Fopen");
  }
  ~FileEditor() { H5Fclose(file_); }
  FileEditor(const FileEditor&) = delete;
  FileEditor& operator=(const FileEditor&) = delete;

  void RemoveAttribute(const std::string& object, const std::string& name) {
    Require(H5Adelete_by_name(file_, object.c_str(), name.c_str(), H5P_DEFAULT), "H5Adelete");
  }

  //! A string attribute, variable-length (as h5py writes str) or fixed-length with `pad`.
  void SetString(const std::string& object, const std::string& name, const std::string& value,
                 bool variable = false, H5T_str_t pad = H5T_STR_NULLTERM) {
    const hid_t type = H5Tcopy(H5T_C_S1);
    if (variable) {
      H5Tset_size(type, H5T_VARIABLE);
      H5Tset_cset(type, H5T_CSET_UTF8);
    } else {
      H5Tset_size(type, std::max<std::size_t>(value.size(), 1));
      H5Tset_strpad(type, pad);
    }
    const hid_t space = H5Screate(H5S_SCALAR);
    const hid_t attribute = Recreate(object, name, type, space);
    const char* text = value.c_str();
    std::string fixed = value;
    fixed.resize(std::max<std::size_t>(value.size(), 1), '\0');
    Require(variable ? H5Awrite(attribute, type, &text) : H5Awrite(attribute, type, fixed.data()),
            "H5Awrite");
    H5Aclose(attribute);
    H5Sclose(space);
    H5Tclose(type);
  }

  //! A numeric attribute of `file_type`, scalar or (as MATLAB writes) of shape `dims`.
  void SetNumber(const std::string& object, const std::string& name, double value,
                 hid_t file_type = H5T_IEEE_F64LE, std::vector<hsize_t> dims = {}) {
    const hid_t space = dims.empty()
                            ? H5Screate(H5S_SCALAR)
                            : H5Screate_simple(static_cast<int>(dims.size()), dims.data(), nullptr);
    const hid_t attribute = Recreate(object, name, file_type, space);
    Require(H5Awrite(attribute, H5T_NATIVE_DOUBLE, &value), "H5Awrite");
    H5Aclose(attribute);
    H5Sclose(space);
  }

  void Remove(const std::string& link) {
    Require(H5Ldelete(file_, link.c_str(), H5P_DEFAULT), "H5Ldelete");
  }

  //! Replaces (or creates) a dataset with `values` in shape `dims` and optional units/reference.
  void SetDataset(const std::string& path, const std::vector<double>& values,
                  std::vector<hsize_t> dims, const char* units, const char* reference = nullptr,
                  hid_t file_type = H5T_IEEE_F64LE) {
    if (H5Lexists(file_, path.c_str(), H5P_DEFAULT) > 0) Remove(path);
    const hid_t space = H5Screate_simple(static_cast<int>(dims.size()), dims.data(), nullptr);
    const hid_t dataset =
        H5Dcreate2(file_, path.c_str(), file_type, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    Require(dataset, "H5Dcreate2");
    if (!values.empty()) {
      Require(H5Dwrite(dataset, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()),
              "H5Dwrite");
    }
    H5Dclose(dataset);
    H5Sclose(space);
    if (units != nullptr) SetString(path, "units", units);
    if (reference != nullptr) SetString(path, "reference", reference);
  }

  //! Overwrites the samples of an existing dataset (same length).
  void Overwrite(const std::string& path, const std::vector<double>& values) {
    const hid_t dataset = H5Dopen2(file_, path.c_str(), H5P_DEFAULT);
    Require(dataset, "H5Dopen2");
    Require(H5Dwrite(dataset, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()),
            "H5Dwrite");
    H5Dclose(dataset);
  }

  //! Rewrites the four contract datasets of an experiment with `n` samples.
  void Resize(const std::string& experiment, std::size_t n, double sample_rate,
              const char* reference) {
    const std::vector<double> t = TimeAxis(n, sample_rate);
    const std::vector<double> ones(n, 1.0);
    const std::vector<hsize_t> dims = {n};
    SetDataset(experiment + "/time", t, dims, "s");
    SetDataset(experiment + "/stroke", ones, dims, "m");
    SetDataset(experiment + "/force", ones, dims, "N");
    SetDataset(experiment + "/pressure", ones, dims, "Pa", reference);
  }

  hid_t get() const { return file_; }

 private:
  hid_t Recreate(const std::string& object, const std::string& name, hid_t type, hid_t space) {
    if (H5Aexists_by_name(file_, object.c_str(), name.c_str(), H5P_DEFAULT) > 0) {
      RemoveAttribute(object, name);
    }
    const hid_t attribute = H5Acreate_by_name(file_, object.c_str(), name.c_str(), type, space,
                                              H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    Require(attribute, "H5Acreate_by_name");
    return attribute;
  }

  hid_t file_;
};

}  // namespace strut::test
