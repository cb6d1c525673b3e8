#include "strut/daq/device_error.h"

#include <utility>

namespace strut::daq {

namespace {

std::string Compose(const std::string& device, const std::string& operation, const std::string& item,
                    const std::string& detail) {
  std::string text = device + ": " + operation;
  if (!item.empty()) text += " " + item;
  return text + ": " + detail;
}

}  // namespace

DeviceError::DeviceError(Kind kind, std::string device, std::string operation, std::string item, int error_number,
                         std::string detail)
    : std::runtime_error(Compose(device, operation, item, detail)),
      kind_(kind),
      device_(std::move(device)),
      operation_(std::move(operation)),
      item_(std::move(item)),
      error_number_(error_number),
      detail_(std::move(detail)) {}

std::string_view ToString(DeviceError::Kind kind) {
  switch (kind) {
    case DeviceError::Kind::kTimeout: return "timeout";
    case DeviceError::Kind::kConnection: return "connection";
    case DeviceError::Kind::kRefused: return "refused";
    case DeviceError::Kind::kInvalidValue: return "invalid value";
    case DeviceError::Kind::kProtocol: return "protocol";
  }
  return "unknown";
}

}  // namespace strut::daq
