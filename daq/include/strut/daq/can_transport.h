// CAN transports: how frames reach strut. Every transport carries the exact bytes of Linux's
// `struct can_frame` (16 bytes, CAN_MTU) or `struct canfd_frame` (72 bytes, CANFD_MTU), so the
// acquisition above it cannot tell a kernel socket from a test transport.
// - SocketCanTransport: a real AF_CAN CAN_RAW socket on an interface (can0, vcan0), error frames
//   enabled with CAN_RAW_ERR_FILTER, CAN FD frames with CAN_RAW_FD_FRAMES.
// - UdpCanTransport: one frame per UDP datagram, the same bytes; tests and the simulated rig use
//   it on loopback (the build machines have no AF_CAN). docs/can-acquisition.md.
#pragma once

#include <linux/can.h>

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>

namespace strut::daq {

//! One frame as SocketCAN carries it. Classic frames use the first CAN_MTU bytes of `raw`
//! (struct can_frame and struct canfd_frame share that layout).
struct CanFrame {
  canfd_frame raw{};
  bool fd = false;  //!< a struct canfd_frame (72 bytes on the wire) rather than a struct can_frame (16)

  std::size_t wire_size() const { return fd ? CANFD_MTU : CAN_MTU; }
  std::uint8_t len() const { return raw.len; }
  //! The frame from the bytes of one transport unit (a datagram, a read()): exactly CAN_MTU or
  //! CANFD_MTU bytes with a payload length the format allows; nullopt for anything else.
  static std::optional<CanFrame> FromBytes(std::span<const std::uint8_t> bytes);
};

//! Counters a transport keeps while receiving.
struct CanTransportCounters {
  std::uint64_t malformed = 0;  //!< units that were no CAN frame (wrong size or length); dropped
  std::uint64_t dropped = 0;    //!< frames the kernel dropped for a full receive queue (SO_RXQ_OVFL)
};

//! How CAN frames are sent and received. One thread owns a transport.
class CanTransport {
 public:
  virtual ~CanTransport() = default;
  //! For messages: "can0", "udp:127.0.0.1:5000".
  virtual const std::string& name() const = 0;
  //! Sends the frames in order, waiting at most `timeout` for room in the send queue.
  //! Throws DeviceError naming the transport on failure or timeout.
  virtual void Send(std::span<const CanFrame> frames, std::chrono::nanoseconds timeout) = 0;
  //! Waits at most `timeout` for frames and returns how many were stored at the front of
  //! `frames` (0 on timeout). Returns as soon as at least one frame is there. Throws
  //! DeviceError naming the transport when the socket fails.
  virtual std::size_t Receive(std::span<CanFrame> frames, std::chrono::nanoseconds timeout) = 0;
  //! Discards what is queued for reception (Start of a new stream).
  virtual void Flush() = 0;
  virtual CanTransportCounters counters() const = 0;
};

//! A transport over one socket it owns and closes: a frame is one write and one read of its bytes
//! on a CAN_RAW socket and on a UDP socket alike.
class SocketFrameTransport : public CanTransport {
 public:
  ~SocketFrameTransport() override;
  SocketFrameTransport(const SocketFrameTransport&) = delete;
  SocketFrameTransport& operator=(const SocketFrameTransport&) = delete;

  const std::string& name() const override { return name_; }
  void Send(std::span<const CanFrame> frames, std::chrono::nanoseconds timeout) override;
  std::size_t Receive(std::span<CanFrame> frames, std::chrono::nanoseconds timeout) override;
  void Flush() override;
  CanTransportCounters counters() const override { return counters_; }

 protected:
  //! `socket` -1: the derived constructor opens it.
  SocketFrameTransport(std::string name, int socket) : name_(std::move(name)), socket_(socket) {}

  std::string name_;
  int socket_ = -1;
  CanTransportCounters counters_;
};

//! A CAN_RAW socket bound to an interface. Throws DeviceError "can0: open: ..." when
//! the socket cannot be created or bound (no AF_CAN in the kernel, no such interface).
class SocketCanTransport : public SocketFrameTransport {
 public:
  //! `fd_frames`: accept and send CAN FD frames (CAN_RAW_FD_FRAMES).
  explicit SocketCanTransport(const std::string& interface, bool fd_frames = true);

  //! Receive only these extended ids (exact), plus error frames. Empty: everything.
  void SetFilter(std::span<const canid_t> extended_ids);
};

//! CAN frames in UDP datagrams, one frame per datagram, the exact struct bytes.
class UdpCanTransport : public SocketFrameTransport {
 public:
  //! Receives on host:port (port 0: an ephemeral port, see local_port()). `receive_buffer`:
  //! SO_RCVBUF bytes asked for (the kernel caps it at net.core.rmem_max); 4 MiB hold
  //! roughly a second of CAN FD frames at 50 kHz (each datagram costs about 1 kB of buffer).
  static std::unique_ptr<UdpCanTransport> Listen(const std::string& host, std::uint16_t port,
                                                 int receive_buffer = 4 << 20);
  //! Sends to host:port.
  static std::unique_ptr<UdpCanTransport> Connect(const std::string& host, std::uint16_t port);

  std::uint16_t local_port() const;

 private:
  UdpCanTransport(std::string name, int socket) : SocketFrameTransport(std::move(name), socket) {}
};

//! A transport from a spec: "can:IFACE" (SocketCAN) or "udp:HOST:PORT" (listening when
//! `listen`, else sending). Throws DeviceError naming the spec when it is not one of these.
std::unique_ptr<CanTransport> OpenCanTransport(const std::string& spec, bool listen, bool fd_frames = true);

}  // namespace strut::daq
