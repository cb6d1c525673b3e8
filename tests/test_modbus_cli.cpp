// strut rig controller-status against strut's controller server on loopback.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "strut/daq/fake_controller.h"
#include "strut/daq/modbus_controller.h"
#include "strut_cli.h"

namespace strut::daq {
namespace {

SetPoint Typical() {
  SetPoint s;
  s.static_position = 0.125;
  s.amplitude = 0.03125;
  s.frequency = 2.5;
  s.ramp_cycles = 3;
  s.static_rate = 0.015625;
  s.limits = {0.0, 0.34375, -4.0e4, 4.5e4};
  return s;
}

TEST(ModbusCli, ControllerStatusPrintsTheStatusAndSetPoint) {
  FakeControllerBackend backend;
  ModbusControllerServer server(backend);
  {
    ModbusController client(ModbusControllerOptions{.endpoint = server.endpoint()});
    client.WriteSetPoint(Typical());
    client.Arm();
  }
  backend.InjectFault(fault_bits::kForceLimit);
  const std::string endpoint = "127.0.0.1:" + std::to_string(server.port());

  const test::CommandResult text = test::RunStrut("rig controller-status --modbus " + endpoint);
  ASSERT_EQ(text.exit_code, 0) << text.output;
  EXPECT_NE(text.output.find("state       faulted (stroke control)"), std::string::npos) << text.output;
  EXPECT_NE(text.output.find("faults      0x0002 force-limit"), std::string::npos) << text.output;
  EXPECT_NE(text.output.find("amplitude 0.03125 m at 2.5 Hz, ramp 3 cycles"), std::string::npos) << text.output;
  EXPECT_NE(text.output.find("sequence    1"), std::string::npos) << text.output;

  const test::CommandResult json = test::RunStrut("-q rig controller-status --json --modbus modbus-tcp://" + endpoint);
  ASSERT_EQ(json.exit_code, 0) << json.output;
  const nlohmann::json j = nlohmann::json::parse(json.output);
  EXPECT_EQ(j["controller"], "modbus-tcp://" + endpoint);
  EXPECT_EQ(j["status"]["state"], "faulted");
  EXPECT_EQ(j["status"]["fault_word"], fault_bits::kForceLimit);
  EXPECT_EQ(j["set_point"]["frequency"], 2.5);
  EXPECT_EQ(j["set_point"]["stroke_max"], 0.34375);
}

TEST(ModbusCli, UnreachableOrMalformedEndpointIsAClearError) {
  int port;
  {
    FakeControllerBackend backend;
    ModbusControllerServer gone(backend);
    port = gone.port();
  }
  const test::CommandResult down = test::RunStrut("rig controller-status --timeout 300 --modbus 127.0.0.1:" +
                                                  std::to_string(port));
  EXPECT_EQ(down.exit_code, 1) << down.output;
  EXPECT_NE(down.output.find("modbus-tcp://127.0.0.1:" + std::to_string(port)), std::string::npos) << down.output;
  EXPECT_NE(down.output.find("Connection refused"), std::string::npos) << down.output;

  const test::CommandResult bad = test::RunStrut("rig controller-status --modbus 127.0.0.1");
  EXPECT_EQ(bad.exit_code, 1) << bad.output;
  EXPECT_NE(bad.output.find("Modbus endpoint '127.0.0.1': no port"), std::string::npos) << bad.output;
}

}  // namespace
}  // namespace strut::daq
