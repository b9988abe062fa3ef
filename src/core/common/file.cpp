#include "ddace/common/file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <filesystem>
#include <istream>
#include <system_error>

#include "ddace/common/error.h"

namespace ddace {
namespace {

std::string reason(int error_number) {
  return std::error_code(error_number, std::generic_category()).message();
}

[[noreturn]] void refuse(const std::string& path, const std::string& message) {
  throw Error(Diagnostic{path, 0, 0, message});
}

const char* kindOf(mode_t mode) {
  if (S_ISDIR(mode)) return "a directory";
  if (S_ISFIFO(mode)) return "a FIFO (named pipe)";
  if (S_ISCHR(mode)) return "a character device";
  if (S_ISBLK(mode)) return "a block device";
  if (S_ISSOCK(mode)) return "a socket";
  return "not a regular file";
}

void checkRegular(const std::string& path, const struct stat& st, std::uint64_t max_bytes) {
  if (!S_ISREG(st.st_mode)) refuse(path, std::string("cannot read: is ") + kindOf(st.st_mode) + ", not a regular file");
  if (static_cast<std::uint64_t>(st.st_size) > max_bytes)
    refuse(path, "cannot read: " + std::to_string(st.st_size) + " bytes, more than the limit of " +
                     std::to_string(max_bytes) + " bytes");
}

// Opens a regular file for reading. The name is checked first (stat does not open, so a
// FIFO cannot block); O_NONBLOCK and the fstat after opening close the window in which the
// name could be replaced by a FIFO or a device.
int openRegular(const std::string& path, std::uint64_t max_bytes) {
  checkInputFile(path, max_bytes);
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY);
  if (fd < 0) refuse(path, "cannot open: " + reason(errno));
  struct stat st {};
  if (::fstat(fd, &st) != 0) {
    const int e = errno;
    ::close(fd);
    refuse(path, "cannot read: " + reason(e));
  }
  if (!S_ISREG(st.st_mode) || static_cast<std::uint64_t>(st.st_size) > max_bytes) {
    ::close(fd);
    checkRegular(path, st, max_bytes);  // throws
  }
  ::fcntl(fd, F_SETFL, ::fcntl(fd, F_GETFL) & ~O_NONBLOCK);
  return fd;
}

// read() that retries on EINTR; -1 with errno on failure.
ssize_t readSome(int fd, char* data, std::size_t size) {
  for (;;) {
    const ssize_t n = ::read(fd, data, size);
    if (n >= 0 || errno != EINTR) return n;
  }
}

std::string tooLarge(std::uint64_t max_bytes) {
  return "cannot read: more than the limit of " + std::to_string(max_bytes) + " bytes";
}

bool underSpecialTree(const std::string& path) {
  return path.rfind("/dev/", 0) == 0 || path.rfind("/proc/", 0) == 0;
}

}  // namespace

std::uint64_t checkInputFile(const std::string& path, std::uint64_t max_bytes) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) refuse(path, "cannot read: " + reason(errno));
  checkRegular(path, st, max_bytes);
  return static_cast<std::uint64_t>(st.st_size);
}

std::string readTextFile(const std::string& path, std::uint64_t max_bytes) {
  const int fd = openRegular(path, max_bytes);
  struct stat st {};
  ::fstat(fd, &st);
  std::string bytes;
  bytes.reserve(static_cast<std::size_t>(st.st_size));
  char chunk[65536];
  for (;;) {
    const ssize_t n = readSome(fd, chunk, sizeof chunk);
    if (n < 0) {
      const int e = errno;
      ::close(fd);
      refuse(path, "cannot read: " + reason(e));
    }
    if (n == 0) break;
    if (bytes.size() + static_cast<std::size_t>(n) > max_bytes) {
      ::close(fd);
      refuse(path, tooLarge(max_bytes));
    }
    bytes.append(chunk, static_cast<std::size_t>(n));
  }
  ::close(fd);
  return bytes;
}

// ------------------------------------------------------------------ InputFile

class InputFile::Buffer : public std::streambuf {
 public:
  Buffer(std::string path, int fd, std::uint64_t max_bytes) : path_(std::move(path)), fd_(fd), left_(max_bytes) {}
  ~Buffer() override { ::close(fd_); }
  bool exceeded() const { return exceeded_; }

 protected:
  int_type underflow() override {
    if (gptr() < egptr()) return traits_type::to_int_type(*gptr());
    if (left_ == 0) {
      // At the bound: one more byte tells whether the file is longer.
      char probe;
      if (!exceeded_ && readSome(fd_, &probe, 1) > 0) exceeded_ = true;
      return traits_type::eof();
    }
    const std::size_t want = left_ < sizeof data_ ? static_cast<std::size_t>(left_) : sizeof data_;
    const ssize_t n = readSome(fd_, data_, want);
    if (n < 0) refuse(path_, "cannot read: " + reason(errno));
    if (n == 0) return traits_type::eof();
    left_ -= static_cast<std::uint64_t>(n);
    setg(data_, data_, data_ + n);
    return traits_type::to_int_type(*gptr());
  }

 private:
  std::string path_;
  int fd_;
  std::uint64_t left_;
  bool exceeded_ = false;
  char data_[65536];
};

InputFile::InputFile(const std::string& path, std::uint64_t max_bytes)
    : path_(path),
      buffer_(std::make_unique<Buffer>(path, openRegular(path, max_bytes), max_bytes)),
      stream_(std::make_unique<std::istream>(buffer_.get())) {
  // A read error thrown by the buffer reaches the caller instead of just setting badbit.
  stream_->exceptions(std::ios::badbit);
}

InputFile::~InputFile() = default;
std::istream& InputFile::stream() {
  return *stream_;
}
bool InputFile::exceeded() const {
  return buffer_->exceeded();
}

// ------------------------------------------------------------------ OutputFile

// Writes straight to the descriptor in 64 kB pieces; the first error is kept (and no
// more is written) for commit() to report.
class OutputFile::Buffer : public std::streambuf {
 public:
  explicit Buffer(int fd) : fd_(fd) { setp(data_, data_ + sizeof data_); }
  int error() const { return error_; }
  bool drain() {
    const char* p = pbase();
    while (error_ == 0 && p < pptr()) {
      const ssize_t n = ::write(fd_, p, static_cast<std::size_t>(pptr() - p));
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) error_ = n < 0 ? errno : EIO;
      else p += n;
    }
    setp(data_, data_ + sizeof data_);
    return error_ == 0;
  }

 protected:
  int_type overflow(int_type c) override {
    if (!drain()) return traits_type::eof();
    if (!traits_type::eq_int_type(c, traits_type::eof())) sputc(traits_type::to_char_type(c));
    return traits_type::not_eof(c);
  }
  int sync() override { return drain() ? 0 : -1; }

 private:
  int fd_;
  int error_ = 0;
  char data_[65536];
};

OutputFile::OutputFile(const std::string& path) : path_(path) {
  if (path.empty()) refuse(path, "cannot write: empty file name");
  namespace fs = std::filesystem;
  struct stat st {};
  bool replace_existing = false;
  if (::stat(path.c_str(), &st) == 0) {
    if (S_ISDIR(st.st_mode)) refuse(path, "cannot write: is a directory");
    if (!S_ISREG(st.st_mode) || underSpecialTree(path)) {
      // A terminal, a pipe, /dev/stdout, a device: there is nothing to replace atomically,
      // the bytes go straight to it (appending, so a `>>` redirection of stdout is kept).
      fd_ = ::open(path.c_str(), O_WRONLY | O_APPEND | O_CLOEXEC | O_NOCTTY);
      if (fd_ < 0) refuse(path, "cannot open for writing: " + reason(errno));
      final_ = path;
    } else {
      // A read-only file stays as it is (the rename below would replace it regardless).
      if (::access(path.c_str(), W_OK) != 0) refuse(path, "cannot write: " + reason(errno));
      std::error_code ec;
      final_ = fs::canonical(path, ec).string();  // replace what a symlink points to, keep the link
      if (ec) final_ = path;
      replace_existing = true;
    }
  } else if (errno == ENOENT) {
    final_ = path;
  } else {
    refuse(path, "cannot write: " + reason(errno));
  }

  if (fd_ < 0) {
    const fs::path target(final_);
    const fs::path dir = target.has_parent_path() ? target.parent_path() : fs::path(".");
    static std::atomic<unsigned> counter{0};
    int e = 0;
    for (int attempt = 0; attempt < 100 && fd_ < 0; ++attempt) {
      temporary_ = (dir / ("." + target.filename().string() + ".tmp-" + std::to_string(::getpid()) + "-" +
                           std::to_string(counter++)))
                       .string();
      fd_ = ::open(temporary_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC | O_NOCTTY, 0666);
      e = errno;
      if (fd_ < 0 && e != EEXIST) break;
    }
    if (fd_ < 0) {
      temporary_.clear();
      refuse(path, "cannot create a temporary file in " + dir.string() + " to write it: " + reason(e));
    }
    if (replace_existing) ::fchmod(fd_, st.st_mode & 07777);
  }
  buffer_ = std::make_unique<Buffer>(fd_);
  stream_ = std::make_unique<std::ostream>(buffer_.get());
}

OutputFile::~OutputFile() {
  if (!committed_) discard();
}

std::ostream& OutputFile::stream() {
  return *stream_;
}

void OutputFile::write(std::string_view bytes) {
  stream_->write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  if (buffer_->error() != 0) fail("cannot write", buffer_->error());
}

void OutputFile::discard() noexcept {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
  if (!temporary_.empty()) ::unlink(temporary_.c_str());
  temporary_.clear();
}

void OutputFile::fail(const std::string& what, int error_number) {
  discard();
  committed_ = true;  // nothing left to undo
  refuse(path_, what + ": " + reason(error_number));
}

void OutputFile::commit() {
  if (committed_) refuse(path_, "cannot write: already committed or failed");
  stream_->flush();
  if (buffer_->error() != 0) fail("cannot write", buffer_->error());
  if (::fsync(fd_) != 0) {
    // Terminals, pipes and character devices cannot be synced (EINVAL); a regular file must be.
    if (!temporary_.empty() || (errno != EINVAL && errno != EROFS && errno != ENOTSUP)) fail("cannot write", errno);
  }
  const int fd = fd_;
  fd_ = -1;
  if (::close(fd) != 0) fail("cannot write (close)", errno);
  if (!temporary_.empty()) {
    if (::rename(temporary_.c_str(), final_.c_str()) != 0) fail("cannot write (rename)", errno);
    temporary_.clear();
    // The rename is durable once the directory is synced (best effort: not every file system can).
    const std::filesystem::path dir = std::filesystem::path(final_).parent_path();
    const int dfd = ::open(dir.empty() ? "." : dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (dfd >= 0) {
      ::fsync(dfd);
      ::close(dfd);
    }
  }
  committed_ = true;
}

void writeTextFile(const std::string& path, std::string_view content) {
  OutputFile out(path);
  out.write(content);
  out.commit();
}

}  // namespace ddace
