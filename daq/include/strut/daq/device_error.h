// The one error type of the device drivers (daq/): what failed, on which device and register,
// and why, with the operating system's or the protocol library's own text.
#pragma once

#include <stdexcept>
#include <string>
#include <string_view>

namespace strut::daq {

//! A device operation that did not succeed. what() reads
//! "DEVICE: OPERATION ITEM: DETAIL", e.g.
//! "modbus-tcp://127.0.0.1:1502: read input registers 0-15 (status block): Connection timed out".
class DeviceError : public std::runtime_error {
 public:
  enum class Kind {
    kTimeout,       //!< no (complete) answer within the configured timeout
    kConnection,    //!< not connected, connection refused, lost or reset
    kRefused,       //!< the device answered with a refusal (e.g. a Modbus exception response)
    kInvalidValue,  //!< a value given to or read from the device is out of range, NaN or malformed
    kProtocol,      //!< an answer that breaks the protocol (wrong length, transaction id, function)
  };

  //! `error_number` is errno (or a library code extending it); 0 when there is none.
  DeviceError(Kind kind, std::string device, std::string operation, std::string item, int error_number,
              std::string detail);

  Kind kind() const { return kind_; }
  const std::string& device() const { return device_; }
  const std::string& operation() const { return operation_; }
  //! The register, channel or frame the operation was about (may be empty).
  const std::string& item() const { return item_; }
  int error_number() const { return error_number_; }
  const std::string& detail() const { return detail_; }

 private:
  Kind kind_;
  std::string device_, operation_, item_;
  int error_number_;
  std::string detail_;
};

std::string_view ToString(DeviceError::Kind kind);

}  // namespace strut::daq
