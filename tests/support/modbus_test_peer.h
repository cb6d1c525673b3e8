// A scripted Modbus TCP peer for the controller tests: answers the first requests like a
// controller (zeros for reads, echoes for writes), then misbehaves as told (silent, late, or
// stalling in the middle of an answer). Raw sockets, no libmodbus: it checks strut's client, not
// its own protocol code. Header-only; one connection at a time.
#pragma once

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "test_support.h"

namespace strut::test {

class ScriptedModbusPeer {
 public:
  enum class Misbehaviour {
    kSilent,         //!< reads the request, never answers
    kLate,           //!< answers after `delay`
    kStallMidAnswer, //!< sends the first 3 bytes of the answer, then nothing
  };

  //! Requests answer_first .. answer_first + misbehave_count - 1 get the misbehaviour.
  ScriptedModbusPeer(int answer_first, Misbehaviour misbehaviour,
                     std::chrono::milliseconds delay = std::chrono::milliseconds(0), int misbehave_count = 1 << 30)
      : answer_first_(answer_first), misbehave_count_(misbehave_count), misbehaviour_(misbehaviour), delay_(delay) {
    listen_fd_ = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (bind(listen_fd_, reinterpret_cast<sockaddr*>(&address), sizeof address) != 0 || listen(listen_fd_, 4) != 0)
      throw std::runtime_error("scripted peer: cannot listen");
    socklen_t length = sizeof address;
    getsockname(listen_fd_, reinterpret_cast<sockaddr*>(&address), &length);
    port_ = ntohs(address.sin_port);
    thread_ = std::thread([this] { Run(); });
  }
  ~ScriptedModbusPeer() {
    stop_ = true;
    thread_.join();
    close(listen_fd_);
  }
  int port() const { return port_; }
  int requests() const { return requests_.load(); }

 private:
  bool WaitReadable(int fd) {
    pollfd p{fd, POLLIN, 0};
    while (!stop_) {
      if (poll(&p, 1, 20) > 0) return true;
    }
    return false;
  }
  bool ReadExactly(int fd, std::uint8_t* out, std::size_t n) {
    std::size_t got = 0;
    while (got < n) {
      if (!WaitReadable(fd)) return false;
      const ssize_t r = recv(fd, out + got, n - got, 0);
      if (r <= 0) return false;
      got += static_cast<std::size_t>(r);
    }
    return true;
  }
  static std::vector<std::uint8_t> Answer(const std::uint8_t* mbap, const std::vector<std::uint8_t>& pdu) {
    std::vector<std::uint8_t> body;
    const std::uint8_t function = pdu.at(0);
    if (function == 3 || function == 4) {
      const int count = (pdu.at(3) << 8) | pdu.at(4);
      body = {function, static_cast<std::uint8_t>(2 * count)};
      body.resize(2 + 2 * static_cast<std::size_t>(count), 0);
    } else if (function == 6) {
      body = pdu;
    } else {
      body.assign(pdu.data(), pdu.data() + 5);
    }
    std::vector<std::uint8_t> adu(7 + body.size());
    adu[0] = mbap[0];
    adu[1] = mbap[1];
    adu[5] = static_cast<std::uint8_t>(body.size() + 1);
    adu[6] = mbap[6];
    std::copy(body.begin(), body.end(), adu.begin() + 7);
    return adu;
  }
  void Serve(int fd) {
    while (!stop_) {
      std::uint8_t mbap[7];
      if (!ReadExactly(fd, mbap, 7)) return;
      const int length = (mbap[4] << 8) | mbap[5];
      if (length < 2 || length > 254) return;
      std::vector<std::uint8_t> pdu(static_cast<std::size_t>(length - 1));
      if (!ReadExactly(fd, pdu.data(), pdu.size()) || pdu.size() < 5) return;  // strut's client sends >= 5
      const int n = requests_++;
      const std::vector<std::uint8_t> answer = Answer(mbap, pdu);
      if (n < answer_first_ || n >= answer_first_ + misbehave_count_) {
        send(fd, answer.data(), answer.size(), MSG_NOSIGNAL);
      } else if (misbehaviour_ == Misbehaviour::kLate) {
        std::this_thread::sleep_for(delay_);
        send(fd, answer.data(), answer.size(), MSG_NOSIGNAL);
      } else if (misbehaviour_ == Misbehaviour::kStallMidAnswer) {
        send(fd, answer.data(), 3, MSG_NOSIGNAL);
      }
    }
  }
  void Run() {
    while (!stop_) {
      if (!WaitReadable(listen_fd_)) return;
      const int fd = accept4(listen_fd_, nullptr, nullptr, SOCK_CLOEXEC);
      if (fd < 0) continue;
      Serve(fd);
      close(fd);
    }
  }

  int answer_first_;
  int misbehave_count_;
  Misbehaviour misbehaviour_;
  std::chrono::milliseconds delay_;
  int listen_fd_ = -1;
  int port_ = 0;
  std::atomic<bool> stop_{false};
  std::atomic<int> requests_{0};
  std::thread thread_;
};

//! Connects to 127.0.0.1:port, sends `bytes`, waits `linger`, closes. Returns false if it could not connect.
inline bool SendRawAndClose(int port, const std::vector<std::uint8_t>& bytes,
                            std::chrono::milliseconds linger = std::chrono::milliseconds(50)) {
  const int fd = ConnectToLoopback(port);
  if (fd < 0) return false;
  send(fd, bytes.data(), bytes.size(), MSG_NOSIGNAL);
  std::this_thread::sleep_for(linger);
  close(fd);
  return true;
}

}  // namespace strut::test
