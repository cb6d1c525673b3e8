// Small RAII wrappers around HDF5 C API identifiers (private to daq).
#pragma once

#include <hdf5.h>

#include <string>
#include <utility>

namespace strut::daq::hdf5 {

//! Owns one HDF5 identifier and closes it with `CloseFn` when it dies.
template <herr_t (*CloseFn)(hid_t)>
class Handle {
 public:
  Handle() = default;
  //! Takes ownership of `id`; a negative id (a failed call) makes an empty handle.
  explicit Handle(hid_t id) : id_(id) {}
  ~Handle() { Close(); }
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;
  Handle(Handle&& other) noexcept : id_(std::exchange(other.id_, H5I_INVALID_HID)) {}
  Handle& operator=(Handle&& other) noexcept {
    if (this != &other) {
      Close();
      id_ = std::exchange(other.id_, H5I_INVALID_HID);
    }
    return *this;
  }

  hid_t get() const { return id_; }
  bool valid() const { return id_ >= 0; }
  explicit operator bool() const { return valid(); }

  //! Closes now and returns the status, so writers can check it (closing a dataset or a file
  //! flushes buffered chunks, which can fail). Closing an empty handle succeeds.
  herr_t Close() {
    if (id_ < 0) return 0;
    return CloseFn(std::exchange(id_, H5I_INVALID_HID));
  }

 private:
  hid_t id_ = H5I_INVALID_HID;
};

using File = Handle<H5Fclose>;
using Group = Handle<H5Gclose>;
using Dataset = Handle<H5Dclose>;
using Attribute = Handle<H5Aclose>;
using Dataspace = Handle<H5Sclose>;
using Datatype = Handle<H5Tclose>;
using PropertyList = Handle<H5Pclose>;
using Object = Handle<H5Oclose>;

//! Turns off HDF5's automatic error-stack printing for its lifetime and restores the previous
//! handler afterwards: strut reports defects itself, with file and item names.
class ErrorSilencer {
 public:
  ErrorSilencer() {
    H5Eget_auto2(H5E_DEFAULT, &func_, &data_);
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  }
  ~ErrorSilencer() { H5Eset_auto2(H5E_DEFAULT, func_, data_); }
  ErrorSilencer(const ErrorSilencer&) = delete;
  ErrorSilencer& operator=(const ErrorSilencer&) = delete;

 private:
  H5E_auto2_t func_ = nullptr;
  void* data_ = nullptr;
};

//! The most specific message on the current HDF5 error stack (empty when none); clears the stack.
std::string TakeErrorMessage();

}  // namespace strut::daq::hdf5
