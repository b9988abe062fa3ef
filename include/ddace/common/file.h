// Reading and writing whole files safely.
//
// Reading: only regular files are read (a FIFO, a device, a directory, a socket or a
// symlink loop is refused by name before anything blocks), up to a size bound, so a
// mistaken path can neither hang a tool nor exhaust memory. The parsers then report
// their own line/column errors on the bytes.
//
// Writing: a file is written to a temporary file next to it and renamed over its name
// only after every byte was written, flushed to disk (fsync) and the file closed
// without error. A failed or interrupted write leaves the old file (or no file) under
// the name, never a half-written one. Targets that are not regular files (a terminal,
// a pipe, /dev/stdout, /dev/full) are written in place with the same checks, so a
// failed write to them is an error too.
//
// Every failure is a ddace::Error whose Diagnostic names the file and the reason
// (the operating system's message for errno).
#pragma once

#include <cstdint>
#include <memory>
#include <ostream>
#include <streambuf>
#include <string>
#include <string_view>

namespace ddace {

/// The default bound on a file read by readTextFile / InputFile: 64 MiB (every config,
/// task file and model text file ddace reads is a few kB to a few MB).
constexpr std::uint64_t kMaxInputFileBytes = std::uint64_t{64} << 20;

/// Throws ddace::Error naming `path` unless it names (after following symlinks) an
/// existing regular file of at most `max_bytes` bytes. Does not open the file, so a
/// FIFO or a device cannot block. Returns the file's size in bytes.
std::uint64_t checkInputFile(const std::string& path, std::uint64_t max_bytes = kMaxInputFileBytes);

/// The bytes of the regular file `path`, at most `max_bytes` of them. Throws
/// ddace::Error naming the file when it does not exist, is not a regular file
/// (directory, FIFO, device, socket, symlink loop), is larger than `max_bytes`
/// (also when it grows past the bound while being read) or cannot be read.
std::string readTextFile(const std::string& path, std::uint64_t max_bytes = kMaxInputFileBytes);

/// A regular file opened for reading as a stream, for readers that process a file
/// piece by piece (memory independent of its size). Same checks as readTextFile when
/// opened; a read error while streaming throws ddace::Error naming the file. The
/// stream ends (eof) after `max_bytes`; exceeded() then tells whether the file was
/// longer, so a reader can refuse it instead of silently using a truncated file.
class InputFile {
 public:
  explicit InputFile(const std::string& path, std::uint64_t max_bytes = kMaxInputFileBytes);
  ~InputFile();
  InputFile(const InputFile&) = delete;
  InputFile& operator=(const InputFile&) = delete;

  std::istream& stream();
  /// The file had more than max_bytes bytes (only known once the stream reached its end).
  bool exceeded() const;
  const std::string& path() const { return path_; }

 private:
  class Buffer;
  std::string path_;
  std::unique_ptr<Buffer> buffer_;
  std::unique_ptr<std::istream> stream_;
};

/// A file being written: bytes go to stream() (or write()); commit() makes them the
/// file's content. Destroyed without commit() (an exception, an early return), the
/// temporary file is removed and the old file under `path` stays as it was.
/// Not for concurrent use by several threads.
class OutputFile {
 public:
  /// Opens the temporary file (or the non-regular target). Throws ddace::Error naming
  /// `path` when it is a directory, its directory does not exist or is not writable.
  /// A new file gets mode 0666 minus the umask; a replaced file keeps its mode. A
  /// symlink to a regular file is followed: the file it points to is replaced. A file
  /// the caller may not write (read-only) is refused, not replaced. Being a new file, a
  /// replaced file no longer shares hard links it had.
  explicit OutputFile(const std::string& path);
  ~OutputFile();
  OutputFile(const OutputFile&) = delete;
  OutputFile& operator=(const OutputFile&) = delete;

  std::ostream& stream();
  void write(std::string_view bytes);
  /// Flush, fsync, close and (for a regular file) rename over the final name. Throws
  /// ddace::Error naming `path` and the reason when any of it fails (the first write
  /// error, e.g. "No space left on device"); the old file then stays intact.
  void commit();
  const std::string& path() const { return path_; }

 private:
  class Buffer;
  void fail(const std::string& what, int error_number);
  void discard() noexcept;
  std::string path_;       ///< the name as the caller gave it (for messages)
  std::string final_;      ///< the file that is replaced (symlinks resolved)
  std::string temporary_;  ///< empty when writing in place (non-regular target)
  int fd_ = -1;
  bool committed_ = false;
  std::unique_ptr<Buffer> buffer_;
  std::unique_ptr<std::ostream> stream_;
};

/// Writes `content` as the whole of `path` through OutputFile (checked, atomic).
void writeTextFile(const std::string& path, std::string_view content);

}  // namespace ddace
