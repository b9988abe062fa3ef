// Snapshots of files for tests that check nothing was changed, and the writes that set
// them up: the one copy for every test binary of test/unit/.
#pragma once

#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <stdexcept>
#include <string>

namespace ddace::test {

/// The bytes of `path` ("" when it cannot be read: the comparison then fails).
inline std::string fileBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

/// Writes `bytes` to `path` (replacing it); throws std::runtime_error naming `path` when
/// the write fails, so a test never goes on with a file it did not make.
inline void writeBytes(const std::string& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << bytes;
  out.close();
  if (!out) throw std::runtime_error("cannot write " + path);
}

/// Every regular file below `dir` (path relative to it) with its bytes.
inline std::map<std::string, std::string> fileTree(const std::string& dir) {
  std::map<std::string, std::string> files;
  for (const auto& e : std::filesystem::recursive_directory_iterator(dir))
    if (e.is_regular_file()) files[std::filesystem::relative(e.path(), dir).string()] = fileBytes(e.path().string());
  return files;
}

}  // namespace ddace::test
