// SocketCAN and UDP transports of CAN frames: the same bytes, the same batched socket calls
// (recvmmsg/sendmmsg), every wait bounded by ppoll.
#include "strut/daq/can_transport.h"

#include <arpa/inet.h>
#include <errno.h>
#include <fmt/format.h>
#include <linux/can/error.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <netdb.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cstring>
#include <vector>

#include "strut/daq/acquisition.h"
#include "strut/daq/device_error.h"

namespace strut::daq {
namespace {

constexpr std::size_t kBatch = 64;
// Room beyond the largest frame so that an oversized datagram shows as MSG_TRUNC, not as a frame.
constexpr std::size_t kUnitBuffer = CANFD_MTU + 8;

bool ValidFdLength(std::uint8_t len) {
  return len <= 8 || len == 12 || len == 16 || len == 20 || len == 24 || len == 32 || len == 48 || len == 64;
}

std::string Errno(int e) { return std::strerror(e); }

timespec ToTimespec(std::chrono::nanoseconds d) {
  if (d.count() < 0) d = std::chrono::nanoseconds(0);
  return {static_cast<time_t>(d.count() / 1'000'000'000), static_cast<long>(d.count() % 1'000'000'000)};
}

//! Waits for `events` on the socket until `deadline`; false on timeout. EINTR waits on.
bool WaitFor(int socket, short events, std::chrono::steady_clock::time_point deadline, const std::string& name,
             const char* what) {
  for (;;) {
    const auto left = std::chrono::duration_cast<std::chrono::nanoseconds>(deadline - std::chrono::steady_clock::now());
    pollfd p{socket, events, 0};
    const timespec ts = ToTimespec(left);
    const int r = ppoll(&p, 1, &ts, nullptr);
    if (r > 0) return true;
    if (r == 0) return false;
    if (errno != EINTR) throw DeviceError(DeviceError::Kind::kConnection, name, what, "", errno, "poll: " + Errno(errno));
  }
}

//! One batch of frames from a datagram or CAN_RAW socket.
std::size_t ReceiveFrames(int socket, const std::string& name, std::span<CanFrame> frames,
                          std::chrono::nanoseconds timeout, CanTransportCounters& counters) {
  if (frames.empty()) return 0;
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  if (!WaitFor(socket, POLLIN, deadline, name, "receive from")) return 0;
  const std::size_t n = std::min(frames.size(), kBatch);
  std::array<std::array<std::uint8_t, kUnitBuffer>, kBatch> buffers;
  std::array<iovec, kBatch> iov;
  std::array<mmsghdr, kBatch> msgs{};
  alignas(cmsghdr) std::array<std::array<char, CMSG_SPACE(sizeof(std::uint32_t))>, kBatch> control;
  for (std::size_t i = 0; i < n; ++i) {
    iov[i] = {buffers[i].data(), buffers[i].size()};
    msgs[i].msg_hdr.msg_iov = &iov[i];
    msgs[i].msg_hdr.msg_iovlen = 1;
    msgs[i].msg_hdr.msg_control = control[i].data();
    msgs[i].msg_hdr.msg_controllen = control[i].size();
  }
  const int got = recvmmsg(socket, msgs.data(), static_cast<unsigned>(n), MSG_DONTWAIT, nullptr);
  if (got < 0) {
    if (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR) return 0;
    // A datagram socket reports an earlier ICMP error here once; the socket itself is fine.
    if (errno == ECONNREFUSED) return 0;
    throw DeviceError(DeviceError::Kind::kConnection, name, "receive", "", errno, Errno(errno));
  }
  std::size_t stored = 0;
  for (int i = 0; i < got; ++i) {
    const msghdr& h = msgs[i].msg_hdr;
    for (cmsghdr* c = CMSG_FIRSTHDR(&h); c; c = CMSG_NXTHDR(const_cast<msghdr*>(&h), c))
      if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SO_RXQ_OVFL) {
        std::uint32_t drops = 0;
        std::memcpy(&drops, CMSG_DATA(c), sizeof drops);
        counters.dropped = std::max<std::uint64_t>(counters.dropped, drops);
      }
    const bool truncated = (h.msg_flags & MSG_TRUNC) != 0;
    const auto frame = truncated ? std::nullopt : CanFrame::FromBytes({buffers[i].data(), msgs[i].msg_len});
    if (frame)
      frames[stored++] = *frame;
    else
      ++counters.malformed;
  }
  return stored;
}

//! Sends the frames in batches, waiting for room until the deadline.
void SendFrames(int socket, const std::string& name, std::span<const CanFrame> frames,
                std::chrono::nanoseconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  std::size_t sent = 0;
  std::array<iovec, kBatch> iov;
  std::array<mmsghdr, kBatch> msgs{};
  while (sent < frames.size()) {
    const std::size_t n = std::min(frames.size() - sent, kBatch);
    for (std::size_t i = 0; i < n; ++i) {
      const CanFrame& f = frames[sent + i];
      iov[i] = {const_cast<canfd_frame*>(&f.raw), f.wire_size()};
      msgs[i] = {};
      msgs[i].msg_hdr.msg_iov = &iov[i];
      msgs[i].msg_hdr.msg_iovlen = 1;
    }
    const int r = sendmmsg(socket, msgs.data(), static_cast<unsigned>(n), MSG_DONTWAIT);
    if (r > 0) {
      sent += static_cast<std::size_t>(r);
      continue;
    }
    if (r < 0 && errno == ECONNREFUSED) continue;  // no listener yet (UDP): like a module on a bus, send on
    if (r < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != ENOBUFS && errno != EINTR)
      throw DeviceError(DeviceError::Kind::kConnection, name, "send", "", errno, Errno(errno));
    // A full queue (ENOBUFS is how CAN_RAW says it): wait for room, bounded by the deadline.
    if (!WaitFor(socket, POLLOUT, deadline, name, "send to") || std::chrono::steady_clock::now() > deadline)
      throw DeviceError(DeviceError::Kind::kTimeout, name, "send", "", 0,
                        fmt::format("no room in the send queue within {} ms",
                                    std::chrono::duration_cast<std::chrono::milliseconds>(timeout).count()));
  }
}

void Drain(int socket) {
  std::array<std::uint8_t, kUnitBuffer> buffer;
  while (recv(socket, buffer.data(), buffer.size(), MSG_DONTWAIT) >= 0) {
  }
}

void EnableDropCounter(int socket) {
  const int on = 1;
  setsockopt(socket, SOL_SOCKET, SO_RXQ_OVFL, &on, sizeof on);  // best effort: only the counter is lost
}

}  // namespace

std::optional<CanFrame> CanFrame::FromBytes(std::span<const std::uint8_t> bytes) {
  CanFrame f;
  if (bytes.size() == CAN_MTU) {
    std::memcpy(&f.raw, bytes.data(), CAN_MTU);
    if (f.raw.len > CAN_MAX_DLEN) return std::nullopt;
    f.fd = false;
    return f;
  }
  if (bytes.size() == CANFD_MTU) {
    std::memcpy(&f.raw, bytes.data(), CANFD_MTU);
    if (!ValidFdLength(f.raw.len)) return std::nullopt;
    f.fd = true;
    return f;
  }
  return std::nullopt;
}

SocketFrameTransport::~SocketFrameTransport() {
  if (socket_ >= 0) close(socket_);
}

void SocketFrameTransport::Send(std::span<const CanFrame> frames, std::chrono::nanoseconds timeout) {
  SendFrames(socket_, name_, frames, timeout);
}

std::size_t SocketFrameTransport::Receive(std::span<CanFrame> frames, std::chrono::nanoseconds timeout) {
  return ReceiveFrames(socket_, name_, frames, timeout, counters_);
}

void SocketFrameTransport::Flush() { Drain(socket_); }

// ---------------------------------------------------------------------------------------------
// SocketCAN

SocketCanTransport::SocketCanTransport(const std::string& interface, bool fd_frames)
    : SocketFrameTransport(interface, -1) {
  const auto fail = [&](const std::string& why) {
    const int error = errno;
    if (socket_ >= 0) close(socket_);
    socket_ = -1;
    throw DeviceError(DeviceError::Kind::kConnection, interface, "open", "", error, why);
  };
  if (interface.empty() || interface.size() >= IFNAMSIZ)
    throw DeviceError(DeviceError::Kind::kInvalidValue, fmt::format("CAN interface '{}'", interface), "open", "", 0,
                      "not an interface name");
  socket_ = socket(PF_CAN, SOCK_RAW | SOCK_CLOEXEC, CAN_RAW);
  if (socket_ < 0) fail(fmt::format("{} (is the kernel's AF_CAN/can-raw support loaded?)", Errno(errno)));
  const unsigned index = if_nametoindex(interface.c_str());
  if (index == 0) {
    errno = ENODEV;
    fail("no such network interface");
  }
  const can_err_mask_t errors = CAN_ERR_MASK;  // every error class: bus-off, passive, protocol, ...
  if (setsockopt(socket_, SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &errors, sizeof errors) < 0)
    fail(fmt::format("CAN_RAW_ERR_FILTER: {}", Errno(errno)));
  if (fd_frames) {
    const int on = 1;
    if (setsockopt(socket_, SOL_CAN_RAW, CAN_RAW_FD_FRAMES, &on, sizeof on) < 0)
      fail(fmt::format("CAN_RAW_FD_FRAMES: {} (the kernel has no CAN FD)", Errno(errno)));
  }
  EnableDropCounter(socket_);
  sockaddr_can address{};
  address.can_family = AF_CAN;
  address.can_ifindex = static_cast<int>(index);
  if (bind(socket_, reinterpret_cast<sockaddr*>(&address), sizeof address) < 0) fail(fmt::format("bind: {}", Errno(errno)));
}

void SocketCanTransport::SetFilter(std::span<const canid_t> extended_ids) {
  std::vector<can_filter> filters;
  for (const canid_t id : extended_ids) filters.push_back({id | CAN_EFF_FLAG, CAN_EFF_FLAG | CAN_RTR_FLAG | CAN_EFF_MASK});
  if (setsockopt(socket_, SOL_CAN_RAW, CAN_RAW_FILTER, filters.empty() ? nullptr : filters.data(),
                 static_cast<socklen_t>(filters.size() * sizeof(can_filter))) < 0)
    throw DeviceError(DeviceError::Kind::kConnection, name_, "set", "CAN_RAW_FILTER", errno, Errno(errno));
}

// ---------------------------------------------------------------------------------------------
// UDP

namespace {

sockaddr_in Resolve(const std::string& host, std::uint16_t port, const std::string& name) {
  addrinfo hints{};
  hints.ai_family = AF_INET;
  hints.ai_socktype = SOCK_DGRAM;
  addrinfo* found = nullptr;
  const int r = getaddrinfo(host.c_str(), nullptr, &hints, &found);
  if (r != 0 || !found) throw DeviceError(DeviceError::Kind::kConnection, name, "open", "host " + host, 0, gai_strerror(r));
  sockaddr_in address{};
  std::memcpy(&address, found->ai_addr, sizeof address);
  freeaddrinfo(found);
  address.sin_port = htons(port);
  return address;
}

int UdpSocket(const std::string& name) {
  const int s = socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  if (s < 0) throw DeviceError(DeviceError::Kind::kConnection, name, "open", "", errno, Errno(errno));
  return s;
}

}  // namespace

std::unique_ptr<UdpCanTransport> UdpCanTransport::Listen(const std::string& host, std::uint16_t port,
                                                         int receive_buffer) {
  const std::string name = fmt::format("udp:{}:{}", host, port);
  const sockaddr_in address = Resolve(host, port, name);
  const int s = UdpSocket(name);
  std::unique_ptr<UdpCanTransport> t(new UdpCanTransport(name, s));
  setsockopt(s, SOL_SOCKET, SO_RCVBUF, &receive_buffer, sizeof receive_buffer);
  EnableDropCounter(s);
  if (bind(s, reinterpret_cast<const sockaddr*>(&address), sizeof address) < 0)
    throw DeviceError(DeviceError::Kind::kConnection, name, "open", "", errno, "bind: " + Errno(errno));
  if (port == 0) t->name_ = fmt::format("udp:{}:{}", host, t->local_port());
  return t;
}

std::unique_ptr<UdpCanTransport> UdpCanTransport::Connect(const std::string& host, std::uint16_t port) {
  const std::string name = fmt::format("udp:{}:{}", host, port);
  const sockaddr_in address = Resolve(host, port, name);
  const int s = UdpSocket(name);
  std::unique_ptr<UdpCanTransport> t(new UdpCanTransport(name, s));
  const int buffer = 4 << 20;
  setsockopt(s, SOL_SOCKET, SO_SNDBUF, &buffer, sizeof buffer);
  if (connect(s, reinterpret_cast<const sockaddr*>(&address), sizeof address) < 0)
    throw DeviceError(DeviceError::Kind::kConnection, name, "open", "", errno, "connect: " + Errno(errno));
  return t;
}

std::uint16_t UdpCanTransport::local_port() const {
  sockaddr_in address{};
  socklen_t size = sizeof address;
  if (getsockname(socket_, reinterpret_cast<sockaddr*>(&address), &size) < 0) return 0;
  return ntohs(address.sin_port);
}

std::unique_ptr<CanTransport> OpenCanTransport(const std::string& spec, bool listen, bool fd_frames) {
  if (spec.rfind("can:", 0) == 0) return std::make_unique<SocketCanTransport>(spec.substr(4), fd_frames);
  if (spec.rfind("udp:", 0) == 0) {
    const std::string rest = spec.substr(4);
    const auto colon = rest.rfind(':');
    if (colon != std::string::npos && colon > 0) {
      const std::string port_text = rest.substr(colon + 1);
      char* end = nullptr;
      const long port = std::strtol(port_text.c_str(), &end, 10);
      if (!port_text.empty() && *end == '\0' && port >= 0 && port <= 65535) {
        const std::string host = rest.substr(0, colon);
        return listen ? std::unique_ptr<CanTransport>(UdpCanTransport::Listen(host, static_cast<std::uint16_t>(port)))
                      : std::unique_ptr<CanTransport>(UdpCanTransport::Connect(host, static_cast<std::uint16_t>(port)));
      }
    }
  }
  throw DeviceError(DeviceError::Kind::kInvalidValue, fmt::format("CAN transport '{}'", spec), "open", "", 0,
                    "expected can:IFACE (SocketCAN) or udp:HOST:PORT (CAN frames over UDP)");
}

}  // namespace strut::daq
