#include "infrastructure/serial_port.h"

#include <fcntl.h>
#include <poll.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <utility>

#include "common/error.h"

namespace autodrive::infrastructure {
namespace {

speed_t Speed(int baud) {
  switch (baud) {
    case 9600:
      return B9600;
    case 19200:
      return B19200;
    case 38400:
      return B38400;
    case 57600:
      return B57600;
    case 115200:
      return B115200;
    case 230400:
      return B230400;
    case 460800:
      return B460800;
    case 921600:
      return B921600;
    default:
      throw InputError("unsupported baud rate " + std::to_string(baud));
  }
}

}  // namespace

SerialPort::SerialPort(const std::string& path, int baud) : path_(path) {
  const speed_t speed = Speed(baud);
  fd_ = ::open(path.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
  if (fd_ < 0) throw InputError("cannot open " + path + ": " + std::strerror(errno));
  termios tio{};
  if (::tcgetattr(fd_, &tio) != 0) {
    const int err = errno;
    ::close(fd_);
    fd_ = -1;
    throw InputError(path + " is not a serial port: " + std::strerror(err));
  }
  ::cfmakeraw(&tio);
  tio.c_cflag |= CLOCAL | CREAD;
  tio.c_cflag &= ~static_cast<tcflag_t>(CSTOPB | CRTSCTS);
  // VMIN 1 with O_NONBLOCK: no data is EAGAIN, so that a read of 0 means a hang-up (with
  // VMIN 0 both would read 0).
  tio.c_cc[VMIN] = 1;
  tio.c_cc[VTIME] = 0;
  ::cfsetispeed(&tio, speed);
  ::cfsetospeed(&tio, speed);
  if (::tcsetattr(fd_, TCSANOW, &tio) != 0) {
    const int err = errno;
    ::close(fd_);
    fd_ = -1;
    throw InputError("cannot configure " + path + ": " + std::strerror(err));
  }
  ::tcflush(fd_, TCIOFLUSH);  // stale reports from before we opened it
}

SerialPort::SerialPort(SerialPort&& other) noexcept
    : path_(std::move(other.path_)),
      fd_(std::exchange(other.fd_, -1)),
      error_(std::move(other.error_)) {}

SerialPort& SerialPort::operator=(SerialPort&& other) noexcept {
  if (this != &other) {
    if (fd_ >= 0) ::close(fd_);
    path_ = std::move(other.path_);
    fd_ = std::exchange(other.fd_, -1);
    error_ = std::move(other.error_);
  }
  return *this;
}

SerialPort::~SerialPort() {
  if (fd_ >= 0) ::close(fd_);
}

bool SerialPort::ReadAvailable(std::string& out) {
  if (fd_ < 0) {
    error_ = "not open";
    return false;
  }
  pollfd pfd{fd_, POLLIN, 0};
  if (::poll(&pfd, 1, 0) > 0) {
    if ((pfd.revents & (POLLERR | POLLNVAL)) != 0 ||
        ((pfd.revents & POLLHUP) != 0 && (pfd.revents & POLLIN) == 0)) {
      error_ = "hung up";
      return false;
    }
  }
  char buffer[512];
  for (;;) {
    const ssize_t n = ::read(fd_, buffer, sizeof buffer);
    if (n > 0) {
      out.append(buffer, static_cast<std::size_t>(n));
      continue;
    }
    if (n == 0) {
      // A non-blocking tty with nothing to read fails with EAGAIN; 0 is a hang-up.
      error_ = "hung up";
      return false;
    }
    if (errno == EINTR) continue;
    if (errno == EAGAIN || errno == EWOULDBLOCK) return true;
    error_ = std::strerror(errno);
    return false;
  }
}

bool SerialPort::Write(std::string_view bytes) {
  if (fd_ < 0) {
    error_ = "not open";
    return false;
  }
  std::size_t done = 0;
  int waits = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd_, bytes.data() + done, bytes.size() - done);
    if (n > 0) {
      done += static_cast<std::size_t>(n);
      continue;
    }
    if (n < 0 && errno == EINTR) continue;
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK) && waits < 5) {
      // The output buffer is full: a slow link. Wait briefly for room, then give up.
      ++waits;
      pollfd pfd{fd_, POLLOUT, 0};
      ::poll(&pfd, 1, 10);
      continue;
    }
    error_ = n < 0 ? std::strerror(errno) : "write returned 0";
    return false;
  }
  return true;
}

}  // namespace autodrive::infrastructure
