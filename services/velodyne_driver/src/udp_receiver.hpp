// A bound IPv4 UDP socket for sensor packets: a large receive buffer, kernel arrival stamps
// (SO_TIMESTAMPNS, CLOCK_REALTIME) and the kernel's count of datagrams dropped for want of buffer
// space (SO_RXQ_OVFL). receive() waits at most a timeout, so that the caller's loop can notice a
// shutdown request promptly.
#pragma once

#include <chrono>
#include <cstdint>
#include <optional>
#include <span>
#include <string>

namespace cdc::velodyne_driver {

struct ReceivedDatagram {
  std::size_t size = 0;    // payload bytes written to the buffer
  bool truncated = false;  // the datagram was longer than the buffer (its tail is lost)
  int64_t stamp_ns = 0;    // arrival [ns since the epoch]
  uint16_t port = 0;       // the local port it was addressed to
};

class UdpReceiver {
 public:
  // Binds `address` (dotted IPv4, e.g. 0.0.0.0 or 127.0.0.1) and `port` (0: the kernel picks one) and
  // asks for a receive buffer of `receive_buffer_bytes`. Throws std::runtime_error naming the address,
  // the port and the system's reason when that fails.
  UdpReceiver(const std::string& address, uint16_t port, int receive_buffer_bytes);
  ~UdpReceiver();
  UdpReceiver(const UdpReceiver&) = delete;
  UdpReceiver& operator=(const UdpReceiver&) = delete;

  // The next datagram into `buffer`, or nullopt when none arrived within `timeout`. Throws
  // std::runtime_error on a socket error.
  std::optional<ReceivedDatagram> receive(std::span<uint8_t> buffer, std::chrono::milliseconds timeout);

  uint16_t port() const noexcept { return port_; }
  int receive_buffer_bytes() const noexcept { return receive_buffer_bytes_; }  // as the kernel granted it
  uint64_t kernel_drops() const noexcept { return kernel_drops_; }  // datagrams the socket's full buffer dropped

 private:
  int fd_ = -1;
  uint16_t port_ = 0;
  int receive_buffer_bytes_ = 0;
  uint64_t kernel_drops_ = 0;
};

}  // namespace cdc::velodyne_driver
