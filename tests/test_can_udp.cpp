// The CAN acquisition module end to end over the UDP transport on loopback: the module's sender
// and strut's CanAcquisition talk through real sockets, with faults injected on the wire
// (gaps, corrupted datagrams, error frames, a frozen stream, an overflowing receive queue).
// SocketCAN cannot be opened on the build machines; its test expects the clear error.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <thread>

#include "can_test_support.h"
#include "strut/daq/can_acquisition.h"

namespace strut::daq {
namespace {

using namespace std::chrono_literals;
using test::FourChannelOptions;

//! A receiving module on an ephemeral loopback port and a sender aimed at it.
struct Loopback {
  CanAcquisition* acquisition = nullptr;
  std::unique_ptr<CanAcquisition> owned;
  std::unique_ptr<CanAcquisitionSender> sender;
  std::uint16_t port = 0;

  explicit Loopback(CanAcquisitionOptions options, int status_every = 0, int receive_buffer = 4 << 20) {
    auto receiver = UdpCanTransport::Listen("127.0.0.1", 0, receive_buffer);
    port = receiver->local_port();
    const CanFrameLayout layout = options.layout;
    owned = std::make_unique<CanAcquisition>(std::move(receiver), std::move(options));
    acquisition = owned.get();
    sender = std::make_unique<CanAcquisitionSender>(UdpCanTransport::Connect("127.0.0.1", port), layout, status_every);
    acquisition->Start();
  }
  //! Reads until `sets` sample sets arrived (or `max_empty` empty reads); returns the blocks.
  std::vector<AcquiredBlock> ReadSets(std::size_t sets, int max_empty = 50) {
    std::vector<AcquiredBlock> blocks;
    std::size_t got = 0;
    for (int empty = 0; got < sets && empty < max_empty;) {
      AcquiredBlock b = acquisition->Read(100ms);
      got += b.size();
      if (b.empty()) ++empty;
      blocks.push_back(std::move(b));
    }
    return blocks;
  }
};

//! Sends raw bytes as one datagram to the port: what no CanTransport would send.
void SendRawDatagram(std::uint16_t port, const void* bytes, std::size_t size) {
  const int s = socket(AF_INET, SOCK_DGRAM, 0);
  ASSERT_GE(s, 0);
  sockaddr_in to{};
  to.sin_family = AF_INET;
  to.sin_port = htons(port);
  to.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  EXPECT_EQ(sendto(s, bytes, size, 0, reinterpret_cast<sockaddr*>(&to), sizeof to), static_cast<ssize_t>(size));
  close(s);
}

TEST(CanAcquisitionUdp, SamplesArriveCalibratedWithMonotonicTimestamps) {
  Loopback loop(FourChannelOptions(), 100);
  const auto& cal = loop.acquisition->description().channels;
  std::vector<AcquiredBlock> blocks;
  for (int chunk = 0; chunk < 10; ++chunk) {  // 1000 sets in chunks the receive queue surely holds
    for (int i = chunk * 100; i < (chunk + 1) * 100; ++i) {
      const std::int16_t set[] = {static_cast<std::int16_t>(i), static_cast<std::int16_t>(-i),
                                  static_cast<std::int16_t>(30 * i), static_cast<std::int16_t>(i % 7)};
      loop.sender->Add(set);
    }
    loop.sender->Flush();
    for (auto& b : loop.ReadSets(100)) blocks.push_back(std::move(b));
  }
  std::int64_t previous_time = 0;
  std::uint64_t next = 0;
  for (const AcquiredBlock& b : blocks) {
    EXPECT_TRUE(b.quality.valid()) << b.quality.ToString();
    EXPECT_FALSE(b.quality.has(Quality::kSequenceGap));
    if (b.empty()) continue;
    EXPECT_EQ(b.first_index, next);
    EXPECT_GT(b.clock.utc_ns, 1'700'000'000'000'000'000);  // a UTC time after 2023
    for (std::size_t k = 0; k < b.size(); ++k) {
      const int i = static_cast<int>(b.first_index + k);
      EXPECT_GT(b.time_ns[k], previous_time);
      previous_time = b.time_ns[k];
      ASSERT_EQ(b.counts[0][k], i);
      ASSERT_EQ(b.counts[2][k], static_cast<std::int16_t>(30 * i));
      ASSERT_DOUBLE_EQ(b.values[1][k], -1000.0 + 2.0 * -i);
      ASSERT_DOUBLE_EQ(b.values[2][k], cal[2].calibration.offset + cal[2].calibration.gain * static_cast<std::int16_t>(30 * i));
    }
    next = b.first_index + b.size();
  }
  EXPECT_EQ(next, 1000u);
  EXPECT_TRUE(loop.acquisition->Read(20ms).empty());  // takes the last status frame
  const AcquisitionStats& s = loop.acquisition->stats();
  EXPECT_EQ(s.sample_sets, 1000u);
  EXPECT_EQ(s.lost_sample_sets, 0u);
  EXPECT_EQ(s.corrupt_frames, 0u);
  EXPECT_EQ(s.frames, 1010u);  // 1000 sample frames and 10 status frames
}

TEST(CanAcquisitionUdp, SequenceGapIsRecordedNotHidden) {
  Loopback loop(FourChannelOptions(true, 50000.0));
  for (int i = 0; i < 80; ++i) loop.sender->Add(std::array<std::int16_t, 4>{static_cast<std::int16_t>(i), 0, 0, 0});
  loop.sender->encoder().Skip(40);  // five FD frames the module never sent
  for (int i = 120; i < 200; ++i) loop.sender->Add(std::array<std::int16_t, 4>{static_cast<std::int16_t>(i), 0, 0, 0});
  loop.sender->Flush();
  const auto blocks = loop.ReadSets(160);
  std::size_t gaps = 0;
  for (const AcquiredBlock& b : blocks)
    if (b.quality.has(Quality::kSequenceGap)) {
      ++gaps;
      EXPECT_EQ(b.lost_before, 40u);
      EXPECT_EQ(b.first_index, 120u);
      EXPECT_EQ(b.counts[0][0], 120);
    }
  EXPECT_EQ(gaps, 1u);
  EXPECT_EQ(loop.acquisition->stats().lost_sample_sets, 40u);
  EXPECT_EQ(loop.acquisition->stats().sample_sets, 160u);
}

TEST(CanAcquisitionUdp, DatagramsThatAreNoFrameAreCountedAndFlagged) {
  Loopback loop(FourChannelOptions());
  const std::uint8_t twenty[20] = {};
  SendRawDatagram(loop.port, twenty, sizeof twenty);  // neither 16 nor 72 bytes
  std::uint8_t big[100] = {};
  SendRawDatagram(loop.port, big, sizeof big);  // longer than any frame
  CanFrame nine;
  nine.raw.can_id = CanFrameLayout{}.sample_id(0);
  nine.raw.len = 9;  // a classic frame cannot carry 9 bytes
  SendRawDatagram(loop.port, &nine.raw, CAN_MTU);
  loop.sender->Add(std::array<std::int16_t, 4>{1, 2, 3, 4});
  loop.sender->Flush();
  std::uint64_t corrupt_in_events = 0;
  bool flagged = false;
  for (const auto& b : loop.ReadSets(1)) {
    flagged |= b.quality.has(Quality::kCorruptFrames);
    for (const auto& e : b.events)
      if (e.kind == AcquisitionEvent::Kind::kCorruptFrames) {
        corrupt_in_events += e.count;
        EXPECT_NE(e.text.find("not a CAN frame"), std::string::npos) << e.text;
      }
  }
  EXPECT_TRUE(flagged);
  EXPECT_EQ(corrupt_in_events, 3u);
  EXPECT_EQ(loop.acquisition->stats().malformed_datagrams, 3u);
  EXPECT_EQ(loop.acquisition->stats().sample_sets, 1u);
}

TEST(CanAcquisitionUdp, BusOffErrorFrameMarksTheFollowingDataInvalid) {
  Loopback loop(FourChannelOptions());
  auto& transport = loop.sender->transport();
  for (int i = 0; i < 5; ++i) loop.sender->Add(std::array<std::int16_t, 4>{static_cast<std::int16_t>(i), 0, 0, 0});
  loop.sender->Flush();
  const CanFrame off = test::ErrorFrame(CAN_ERR_BUSOFF);
  transport.Send({&off, 1}, 100ms);
  for (int i = 5; i < 10; ++i) loop.sender->Add(std::array<std::int16_t, 4>{static_cast<std::int16_t>(i), 0, 0, 0});
  loop.sender->Flush();
  std::size_t valid = 0, invalid = 0;
  for (const auto& b : loop.ReadSets(10)) (b.quality.valid() ? valid : invalid) += b.size();
  EXPECT_EQ(valid, 5u);
  EXPECT_EQ(invalid, 5u);
  EXPECT_EQ(loop.acquisition->stats().invalid_sample_sets, 5u);
}

TEST(CanAcquisitionUdp, FrozenStreamIsReportedAndReadNeverOverstaysItsTimeout) {
  auto options = FourChannelOptions();
  options.stale_after = 150ms;
  Loopback loop(options);
  for (int i = 0; i < 4; ++i) loop.sender->Add(std::array<std::int16_t, 4>{static_cast<std::int16_t>(i), 0, 0, 0});
  loop.sender->Flush();
  const auto last_send = std::chrono::steady_clock::now();
  ASSERT_EQ(loop.ReadSets(4).size() > 0, true);
  // The module stops sending. Reads of 40 ms each return on time; the stream turns stale
  // once 150 ms passed without a frame, with one event that says so.
  int stale_events = 0;
  std::chrono::duration<double> stale_after{};
  for (int i = 0; i < 10; ++i) {
    const auto start = std::chrono::steady_clock::now();
    const AcquiredBlock b = loop.acquisition->Read(40ms);
    const auto took = std::chrono::steady_clock::now() - start;
    EXPECT_GE(took, 40ms);
    EXPECT_LT(took, 40ms + 200ms) << "Read waited far past its timeout";  // generous: a shared machine
    EXPECT_TRUE(b.empty());
    for (const auto& e : b.events)
      if (e.kind == AcquisitionEvent::Kind::kStale) {
        ++stale_events;
        stale_after = std::chrono::steady_clock::now() - last_send;
        EXPECT_NE(e.text.find("frozen"), std::string::npos);
      }
    if (stale_events) {
      EXPECT_TRUE(b.quality.has(Quality::kStale));
    }
  }
  EXPECT_EQ(stale_events, 1);
  EXPECT_GE(stale_after, 150ms);
  // The module comes back: the stream resumes, with the event that says so.
  loop.sender->Add(std::array<std::int16_t, 4>{4, 0, 0, 0});
  loop.sender->Flush();
  bool resumed = false;
  for (const auto& b : loop.ReadSets(1))
    for (const auto& e : b.events) resumed |= e.kind == AcquisitionEvent::Kind::kResumed;
  EXPECT_TRUE(resumed);
}

TEST(CanAcquisitionUdp, FramesTheReceiveQueueDroppedShowAsGapsOfTheSameSize) {
  // A receive queue of a few kB overflows when the reader is slow; the kernel's drop counter and
  // the sequence gaps must agree frame for frame.
  Loopback loop(FourChannelOptions(true, 50000.0), 0, 4096);
  for (int i = 0; i < 8 * 400; ++i) loop.sender->Add(std::array<std::int16_t, 4>{static_cast<std::int16_t>(i), 0, 0, 0});
  loop.sender->Flush();
  loop.ReadSets(8 * 400, 1);  // reads what the queue kept
  // One more frame after the queue drained: frames dropped at the end show as its gap.
  for (int i = 0; i < 8; ++i) loop.sender->Add(std::array<std::int16_t, 4>{1, 0, 0, 0});
  loop.sender->Flush();
  loop.ReadSets(8);
  const AcquisitionStats& s = loop.acquisition->stats();
  EXPECT_GT(s.receiver_drops, 0u);
  EXPECT_EQ(s.lost_sample_sets, 8 * s.receiver_drops);
  EXPECT_EQ(s.sample_sets + s.lost_sample_sets, 8u * 401);
}

TEST(CanAcquisitionUdp, ReadBeforeStartIsAnError) {
  auto receiver = UdpCanTransport::Listen("127.0.0.1", 0);
  CanAcquisition acquisition(std::move(receiver), FourChannelOptions());
  try {
    acquisition.Read(10ms);
    FAIL() << "no error";
  } catch (const DeviceError& e) {
    EXPECT_NE(std::string(e.what()).find("udp:127.0.0.1:"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("before Start"), std::string::npos) << e.what();
  }
}

TEST(CanTransport, SocketCanCannotBeOpenedHereAndSaysWhy) {
  // The build machines have no AF_CAN; a machine with it has no can0 either in CI. Both are the
  // same clear error naming the interface.
  try {
    SocketCanTransport t("can0");
    FAIL() << "can0 opened";
  } catch (const DeviceError& e) {
    EXPECT_EQ(std::string(e.what()).rfind("can0: open: ", 0), 0u) << e.what();
    EXPECT_EQ(e.kind(), DeviceError::Kind::kConnection);
  }
  EXPECT_THROW(OpenCanTransport("can:can0", true), DeviceError);
}

TEST(CanTransport, SpecsAreParsedAndBadOnesNamed) {
  auto t = OpenCanTransport("udp:127.0.0.1:0", true);
  EXPECT_EQ(t->name().rfind("udp:127.0.0.1:", 0), 0u);
  EXPECT_NE(t->name(), "udp:127.0.0.1:0");  // the ephemeral port it got
  for (const char* bad : {"udp:127.0.0.1", "udp:127.0.0.1:99999", "serial:/dev/ttyS0", "udp::5000", "udp:h:x"}) {
    try {
      OpenCanTransport(bad, true);
      ADD_FAILURE() << bad << " accepted";
    } catch (const DeviceError& e) {
      EXPECT_NE(std::string(e.what()).find(bad), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace strut::daq
