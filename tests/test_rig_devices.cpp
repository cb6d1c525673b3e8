// The devices of a rig from connection strings (daq/rig_devices.h): the factory that takes a
// connection makes its drivers; strings no factory takes, or that are malformed, are refused
// naming the string; a rig on the network answers through the drivers made for it (a
// ModbusControllerServer with the fake backend in this process, its connect timeout explicit).
#include <gtest/gtest.h>

#include <chrono>
#include <stdexcept>
#include <string>
#include <vector>

#include "strut/daq/device_error.h"
#include "strut/daq/fake_controller.h"
#include "strut/daq/modbus_controller.h"
#include "strut/daq/rig_devices.h"

namespace strut::daq {
namespace {

RigConnection Connection(std::string controller, std::string acquisition) {
  RigConnection c;
  c.controller = std::move(controller);
  c.acquisition = std::move(acquisition);
  c.response_timeout = std::chrono::milliseconds(300);
  c.can.layout.channels = 3;
  c.can.sample_rate = 200.0;
  c.can.channels = {{"stroke", "m", Calibration::FromRange16(-0.01, 0.3)},
                    {"force", "N", Calibration::FromRange16(-60e3, 60e3)},
                    {"pressure", "Pa", Calibration::FromRange16(-0.1e6, 20e6)}};
  return c;
}

//! A kind of rig that takes one controller string and makes no drivers, only a description.
class NamedRigFactory final : public RigDeviceFactory {
 public:
  explicit NamedRigFactory(std::string name) : name_(std::move(name)) {}
  std::string Accepted() const override { return name_ + " (a test's rig)"; }
  bool Accepts(const RigConnection& c) const override { return c.controller == name_; }
  RigDevices Connect(const RigConnection& c) const override {
    RigDevices d;
    d.description = name_ + " connected";
    return d;
  }

 private:
  std::string name_;
};

std::string Refusal(const RigConnection& c, const std::vector<const RigDeviceFactory*>& factories) {
  try {
    ConnectRig(c, factories);
  } catch (const std::exception& e) {  // std::invalid_argument or DeviceError, both name the string
    return e.what();
  }
  return "(not refused)";
}

TEST(RigDevices, TheFirstFactoryThatTakesTheConnectionMakesTheDevices) {
  const NamedRigFactory bench("bench"), other("other");
  const NetworkRigFactory network;
  const std::vector<const RigDeviceFactory*> factories{&bench, &network, &other};
  EXPECT_EQ(ConnectRig(Connection("bench", ""), factories).description, "bench connected");
  EXPECT_EQ(ConnectRig(Connection("other", ""), factories).description, "other connected");
  // The network takes modbus-tcp:// and scheme-less HOST:PORT; not another scheme or a bare name.
  EXPECT_TRUE(network.Accepts(Connection("modbus-tcp://10.0.0.2:502", "can:can0")));
  EXPECT_TRUE(network.Accepts(Connection("10.0.0.2:502", "can:can0")));
  EXPECT_TRUE(network.Accepts(Connection("[::1]:1502", "udp:127.0.0.1:5000")));
  EXPECT_FALSE(network.Accepts(Connection("opc-tcp://10.0.0.2:4840", "can:can0")));
  EXPECT_FALSE(network.Accepts(Connection("sim", "")));
  // None takes it: the string and what each factory takes.
  const std::string none = Refusal(Connection("nowhere", ""), factories);
  EXPECT_EQ(none.rfind("rig 'nowhere': no kind of rig takes it (known: bench (a test's rig); modbus-tcp://", 0), 0u)
      << none;
  EXPECT_NE(none.find("; other (a test's rig))"), std::string::npos) << none;
  EXPECT_NE(Refusal(Connection("bench", ""), {}).find("rig 'bench': no kind of rig takes it (known: )"),
            std::string::npos);
}

TEST(RigDevices, AMalformedNetworkConnectionIsRefusedNamingTheString) {
  const NetworkRigFactory network;
  const std::vector<const RigDeviceFactory*> factories{&network};
  EXPECT_NE(Refusal(Connection("10.0.0.2:99999", "udp:127.0.0.1:0"), factories)
                .find("Modbus endpoint '10.0.0.2:99999': port '99999' is not a number in 1..65535"),
            std::string::npos);
  EXPECT_NE(Refusal(Connection("modbus-tcp://10.0.0.2", "udp:127.0.0.1:0"), factories)
                .find("Modbus endpoint 'modbus-tcp://10.0.0.2': no port"),
            std::string::npos);
  // The acquisition string: not a transport, or a UDP port out of range.
  for (const std::string bad : {"tcp:127.0.0.1:5000", "udp:127.0.0.1:70000", "udp:5000"}) {
    try {
      ConnectRig(Connection("127.0.0.1:1502", bad), factories);
      ADD_FAILURE() << bad << " was taken";
    } catch (const DeviceError& e) {
      EXPECT_EQ(e.device(), "CAN transport '" + bad + "'");
      EXPECT_NE(std::string(e.what()).find("expected can:IFACE (SocketCAN) or udp:HOST:PORT"), std::string::npos);
    }
  }
  // Channels that do not fit the layout: the acquisition's own refusal.
  RigConnection c = Connection("127.0.0.1:1502", "udp:127.0.0.1:0");
  c.can.channels.pop_back();
  EXPECT_THROW(ConnectRig(c, factories), std::invalid_argument);
}

TEST(RigDevices, ARigOnTheNetworkAnswersThroughItsDriversWithinTheTimeout) {
  FakeControllerBackend backend;
  ModbusControllerServer server(backend);
  const NetworkRigFactory network;
  const std::vector<const RigDeviceFactory*> factories{&network};
  const std::string endpoint = "modbus-tcp://127.0.0.1:" + std::to_string(server.port());
  RigDevices devices = ConnectRig(Connection(endpoint, "udp:127.0.0.1:0"), factories);
  EXPECT_EQ(devices.host, nullptr);
  ASSERT_NE(devices.controller, nullptr);
  ASSERT_NE(devices.acquisition, nullptr);
  EXPECT_EQ(devices.description.rfind(endpoint, 0), 0u) << devices.description;
  EXPECT_NE(devices.description.find(" + udp:127.0.0.1:0"), std::string::npos) << devices.description;
  EXPECT_EQ(devices.acquisition->description().channels.size(), 3u);
  EXPECT_DOUBLE_EQ(devices.acquisition->description().sample_rate, 200.0);
  EXPECT_EQ(devices.controller->ReadStatus().state, backend.Status().state);

  // Nothing listens at the port once the server is gone: the controller fails within the
  // connection's timeout (and the backoff), naming the endpoint.
  const int port = server.port();
  RigDevices lost = ConnectRig(Connection("127.0.0.1:" + std::to_string(port), "udp:127.0.0.1:0"), factories);
  server.Stop();
  const auto t0 = std::chrono::steady_clock::now();
  try {
    for (int i = 0; i < 20; ++i) lost.controller->ReadStatus();
    ADD_FAILURE() << "a controller without a server answered";
  } catch (const DeviceError& e) {
    EXPECT_NE(e.device().find("127.0.0.1:" + std::to_string(port)), std::string::npos) << e.what();
  }
  EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(10));
}

}  // namespace
}  // namespace strut::daq
