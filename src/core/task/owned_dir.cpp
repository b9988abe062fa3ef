#include "ddace/task/owned_dir.h"

#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <limits>
#include <map>
#include <sstream>

#include "ddace/common/error.h"
#include "ddace/common/file.h"
#include "ddace/common/sha256.h"

namespace fs = std::filesystem;

namespace ddace::task {
namespace {

/// Marks a temporary directory as ours and unfinished (removed just before the swap).
constexpr const char* kIncompleteMarker = ".ddace-incomplete";

/// A file as the record lists it: size and digest (lower-case hex, of the record's hash).
struct Digest {
  uint64_t size = 0;
  std::string hex;
  bool operator==(const Digest& o) const { return size == o.size && hex == o.hex; }
};

/// The hash of a record. Records are written with SHA-256 only; FNV-1a 64 is read so
/// that an output written before the switch is still recognised as the tool's own.
enum class RecordHash { Sha256, Fnv1a64 };

const char* hashName(RecordHash h) {
  return h == RecordHash::Sha256 ? "SHA-256" : "FNV-1a 64";
}

/// FNV-1a 64 for reading old records only (nothing is written with it).
struct Fnv1a64 {
  uint64_t h = 0xcbf29ce484222325ULL;
  void update(const char* data, size_t n) {
    for (size_t i = 0; i < n; ++i) h = (h ^ static_cast<unsigned char>(data[i])) * 0x100000001b3ULL;
  }
  std::string hex() const {
    char buf[17];
    std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(h));
    return buf;
  }
};

bool isDigestHex(const std::string& hex, RecordHash h) {
  if (h == RecordHash::Sha256) return isSha256Hex(hex);
  return hex.size() == 16 && hex.find_first_not_of("0123456789abcdef") == std::string::npos;
}

Digest digestOf(const std::string& bytes) {
  return {bytes.size(), sha256Hex(bytes)};
}

/// The digest of a regular file with `hash`, streamed (weights can be large). Throws
/// ddace::Error.
Digest digestOfFile(const fs::path& file, RecordHash hash = RecordHash::Sha256) {
  InputFile in(file.string(), std::numeric_limits<uint64_t>::max());
  Sha256 sha;
  Fnv1a64 fnv;
  uint64_t size = 0;
  char buf[1 << 16];
  while (in.stream().read(buf, sizeof buf) || in.stream().gcount() > 0) {
    const auto n = static_cast<size_t>(in.stream().gcount());
    if (hash == RecordHash::Sha256) sha.update(std::string_view(buf, n));
    else fnv.update(buf, n);
    size += n;
  }
  return {size, hash == RecordHash::Sha256 ? sha.hex() : fnv.hex()};
}

/// A record: who wrote it and what (relative path -> digest of `hash`).
struct Manifest {
  bool readable = false;
  std::string writer;
  RecordHash hash = RecordHash::Sha256;
  std::map<std::string, Digest> files;
};

// The header: "# TOOL wrote these files (HASH, bytes, path); it replaces only these".
constexpr const char* kHeaderMiddle = " wrote these files (";
constexpr const char* kHeaderTail = ", bytes, path); it replaces only these";

Manifest readManifest(const fs::path& file) {
  Manifest m;
  std::string text;
  try {
    text = readTextFile(file.string());
  } catch (const Error&) {
    return m;
  }
  std::istringstream in(text);
  std::string line;
  if (!std::getline(in, line) || line.rfind("# ", 0) != 0) return m;
  const size_t middle = line.find(kHeaderMiddle);
  if (middle == std::string::npos || middle <= 2) return m;
  const std::string hash_and_tail = line.substr(middle + std::strlen(kHeaderMiddle));
  bool known = false;
  for (RecordHash h : {RecordHash::Sha256, RecordHash::Fnv1a64})
    if (hash_and_tail == std::string(hashName(h)) + kHeaderTail) {
      m.hash = h;
      known = true;
    }
  if (!known) return m;
  m.writer = line.substr(2, middle - 2);
  while (std::getline(in, line)) {
    std::istringstream fields(line);
    Digest d;
    std::string path;
    if (!(fields >> d.hex >> d.size) || !isDigestHex(d.hex, m.hash)) return m;
    fields >> std::ws;
    std::getline(fields, path);
    if (path.empty()) return m;
    m.files[path] = d;
  }
  m.readable = true;
  return m;
}

/// A new record, always SHA-256.
std::string manifestText(const std::map<std::string, Digest>& files, const std::string& tool) {
  std::string text = "# " + tool + kHeaderMiddle + hashName(RecordHash::Sha256) + kHeaderTail + "\n";
  for (const auto& [path, d] : files) text += d.hex + " " + std::to_string(d.size) + " " + path + "\n";
  return text;
}

/// A relative path inside the directory: not empty, not absolute, no "." or ".." parts.
bool isPlainRelative(const std::string& path) {
  const fs::path p(path);
  if (path.empty() || p.is_absolute()) return false;
  for (const auto& part : p)
    if (part == "." || part == ".." || part.empty()) return false;
  return true;
}

[[noreturn]] void refuse(const fs::path& path, const std::string& message) {
  throw Error(Diagnostic{path.string(), 0, 0, message});
}

struct Survey {
  std::vector<std::string> foreign;  ///< "path (why)"
  size_t own = 0;                    ///< files that are the tool's own
};

/// Everything in `dir` judged as the tool's own or not (nothing is followed or opened
/// but regular files whose size matches a file we know).
Survey survey(const fs::path& dir, const fs::path& shown, const std::map<std::string, Digest>& incoming,
              const std::string& tool) {
  Survey s;
  const Manifest manifest = readManifest(dir / kOwnedManifest);
  const bool mine = manifest.readable && manifest.writer == tool;
  std::map<std::string, bool> parents;  // directories the tool's files live in
  auto addParents = [&](const std::string& rel) {
    for (fs::path p = fs::path(rel).parent_path(); !p.empty(); p = p.parent_path()) parents[p.generic_string()] = true;
  };
  for (const auto& f : incoming) addParents(f.first);
  if (mine)
    for (const auto& m : manifest.files) addParents(m.first);

  std::error_code ec;
  fs::recursive_directory_iterator it(dir, fs::directory_options::none, ec), end;
  for (; !ec && it != end; it.increment(ec)) {
    const fs::path& p = it->path();
    const std::string rel = p.lexically_relative(dir).generic_string();
    const std::string name = (shown / rel).string();  // as the user wrote the directory
    std::error_code sec;
    const fs::file_status st = it->symlink_status(sec);
    if (sec) {
      s.foreign.push_back(name + " (cannot read: " + sec.message() + ")");
      continue;
    }
    if (fs::is_symlink(st)) {
      s.foreign.push_back(name + " (a symbolic link " + tool + " did not create)");
      continue;
    }
    if (fs::is_directory(st)) {
      // A directory is judged by what it holds (listed one by one); an empty one of
      // somebody else's is named itself.
      if (!parents.count(rel) && fs::is_empty(p, sec))
        s.foreign.push_back(name + "/ (a directory " + tool + " did not create)");
      continue;
    }
    if (!fs::is_regular_file(st)) {
      s.foreign.push_back(name + " (not a regular file)");
      continue;
    }
    if (rel == kOwnedManifest) {
      if (mine) ++s.own;
      else if (manifest.readable) s.foreign.push_back(name + " (the manifest of " + manifest.writer + "'s output)");
      else s.foreign.push_back(name + " (not a manifest " + tool + " can read)");
      continue;
    }
    const uint64_t size = fs::file_size(p, sec);
    const auto m = mine ? manifest.files.find(rel) : manifest.files.end();
    const auto n = incoming.find(rel);
    const bool may_be_listed = m != manifest.files.end() && !sec && m->second.size == size;
    const bool may_be_same = n != incoming.end() && !sec && n->second.size == size;
    bool own = false;
    if (may_be_listed || may_be_same) {
      try {
        // The incoming digest is SHA-256, the listed one of the record's hash (FNV-1a 64
        // in an old record: the file is then read once more).
        const Digest sha = digestOfFile(p);
        const bool legacy = may_be_listed && manifest.hash != RecordHash::Sha256;
        const Digest listed = legacy ? digestOfFile(p, manifest.hash) : sha;
        own = (may_be_listed && listed == m->second) || (may_be_same && sha == n->second);
      } catch (const Error&) {
        own = false;
      }
    }
    if (own) ++s.own;
    else if (m != manifest.files.end()) s.foreign.push_back(name + " (changed since " + tool + " wrote it)");
    else if (manifest.readable && !mine && manifest.files.count(rel))
      s.foreign.push_back(name + " (written by " + manifest.writer + ", not " + tool + ")");
    else s.foreign.push_back(name + " (not written by " + tool + ")");
  }
  if (ec) s.foreign.push_back(shown.string() + " (cannot read the directory: " + ec.message() + ")");
  return s;
}

/// `dir` made absolute, a symlink to a directory resolved (its directory is replaced).
fs::path resolveTarget(const std::string& dir) {
  std::error_code ec;
  fs::path target = fs::absolute(fs::path(dir), ec).lexically_normal();
  if (!target.has_filename()) target = target.parent_path();
  if (ec || target == target.root_path()) refuse(dir, "cannot write into this directory");
  const fs::file_status st = fs::status(target, ec);
  if (ec && st.type() != fs::file_type::not_found) refuse(dir, "cannot read: " + ec.message());
  if (fs::exists(st)) {
    if (!fs::is_directory(st)) refuse(dir, "exists and is not a directory");
    target = fs::canonical(target, ec);
    if (ec) refuse(dir, "cannot read: " + ec.message());
  }
  return target;
}

/// Refuses `target` unless it may be replaced by `incoming`; true when it exists.
bool checkTarget(const fs::path& target, const std::string& dir, const std::map<std::string, Digest>& incoming,
                 const std::string& tool, bool replace) {
  std::error_code ec;
  const fs::file_status st = fs::symlink_status(target, ec);
  if (!fs::exists(st)) return false;
  if (!fs::is_directory(st)) refuse(dir, "exists and is not a directory");
  const Survey s = survey(target, fs::path(dir), incoming, tool);
  if (!s.foreign.empty()) {
    std::string list;
    for (size_t i = 0; i < s.foreign.size() && i < 10; ++i) list += "\n  " + s.foreign[i];
    if (s.foreign.size() > 10) list += "\n  ... and " + std::to_string(s.foreign.size() - 10) + " more";
    refuse(dir, "refusing to write here: it holds " + std::to_string(s.foreign.size()) + " entr" +
                    (s.foreign.size() == 1 ? "y " : "ies ") + tool +
                    " did not write (move them away or choose another directory):" + list);
  }
  if (s.own > 0 && !replace) refuse(dir, "holds the output of an earlier " + tool + "; --force replaces it");
  return true;
}

/// Swaps the directories `a` and `b` in one step; falls back to two renames where the
/// file system cannot exchange.
void exchange(const fs::path& a, const fs::path& b) {
  if (::renameat2(AT_FDCWD, a.c_str(), AT_FDCWD, b.c_str(), RENAME_EXCHANGE) == 0) return;
  if (errno != EINVAL && errno != ENOSYS && errno != ENOTSUP)
    refuse(b, std::string("cannot replace the directory: ") + std::strerror(errno));
  const fs::path aside = a.string() + ".old";
  if (::rename(b.c_str(), aside.c_str()) != 0)
    refuse(b, std::string("cannot replace the directory: ") + std::strerror(errno));
  if (::rename(a.c_str(), b.c_str()) != 0) {
    const int e = errno;
    ::rename(aside.c_str(), b.c_str());
    refuse(b, std::string("cannot replace the directory: ") + std::strerror(e));
  }
  ::rename(aside.c_str(), a.c_str());
}

void syncDirectory(const fs::path& dir) {
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd >= 0) {
    ::fsync(fd);
    ::close(fd);
  }
}

/// Removes the temporary siblings of `target` left by killed runs: named
/// ".NAME.tmp-PID-N", a real directory holding the incomplete marker, PID not running.
void removeStaleTemporaries(const fs::path& target) {
  const std::string prefix = "." + target.filename().string() + ".tmp-";
  std::error_code ec;
  for (fs::directory_iterator it(target.parent_path(), ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.rfind(prefix, 0) != 0) continue;
    const std::string rest = name.substr(prefix.size());
    const size_t dash = rest.find('-');
    if (dash == 0 || dash == std::string::npos || rest.find_first_not_of("0123456789-") != std::string::npos) continue;
    const long pid = std::strtol(rest.substr(0, dash).c_str(), nullptr, 10);
    std::error_code sec;
    if (pid <= 0 || pid == ::getpid() || !fs::is_directory(fs::symlink_status(it->path(), sec)) ||
        !fs::is_regular_file(fs::symlink_status(it->path() / kIncompleteMarker, sec)))
      continue;
    if (::kill(static_cast<pid_t>(pid), 0) == 0 || errno != ESRCH) continue;  // still running (or not ours)
    fs::remove_all(it->path(), sec);
  }
}

/// `e` with every mention of the temporary directory replaced by the directory's name.
Error renamed(const Error& e, const std::string& tmp, const std::string& dir) {
  auto replaceAll = [&](std::string s) {
    for (size_t at = s.find(tmp); at != std::string::npos; at = s.find(tmp, at + dir.size()))
      s.replace(at, tmp.size(), dir);
    return s;
  };
  std::vector<Diagnostic> named;
  for (Diagnostic d : e.diagnostics()) {
    d.file = replaceAll(d.file);
    d.message = replaceAll(d.message);
    named.push_back(d);
  }
  return Error(named);
}

/// Every file `fill` wrote into `tmp` with its digest; anything but regular files and
/// directories is an error (it would not be the tool's own to replace next time).
std::map<std::string, Digest> collect(const fs::path& tmp, const std::string& dir) {
  std::map<std::string, Digest> files;
  std::error_code ec;
  fs::recursive_directory_iterator it(tmp, fs::directory_options::none, ec), end;
  for (; !ec && it != end; it.increment(ec)) {
    const std::string rel = it->path().lexically_relative(tmp).generic_string();
    if (rel == kIncompleteMarker) continue;
    std::error_code sec;
    const fs::file_status st = it->symlink_status(sec);
    if (fs::is_directory(st)) continue;
    if (sec || !fs::is_regular_file(st) || rel == kOwnedManifest)
      refuse(fs::path(dir) / rel, "not a regular file of the output (internal error: nothing was replaced)");
    files[rel] = digestOfFile(it->path());
  }
  if (ec) refuse(dir, "cannot read the new output: " + ec.message());
  return files;
}

/// Both writeOwnedDirectory: `expected` (known before `fill` runs, may be empty) lets
/// the first check accept files identical to what is about to be written.
void writeOwned(const std::string& dir, const std::map<std::string, Digest>& expected,
                const std::function<void(const std::string&)>& fill, const std::string& tool, bool replace) {
  const fs::path target = resolveTarget(dir);
  checkTarget(target, dir, expected, tool, replace);

  const fs::path parent = target.parent_path();
  std::error_code ec;
  fs::create_directories(parent, ec);
  if (ec) refuse(parent, "cannot create the directory: " + ec.message());
  removeStaleTemporaries(target);
  static std::atomic<unsigned> counter{0};
  fs::path tmp;
  for (int attempt = 0; attempt < 100; ++attempt) {
    tmp = parent /
          ("." + target.filename().string() + ".tmp-" + std::to_string(::getpid()) + "-" + std::to_string(counter++));
    if (::mkdir(tmp.c_str(), 0777) == 0) break;
    if (errno != EEXIST) refuse(parent, std::string("cannot create a temporary directory: ") + std::strerror(errno));
    tmp.clear();
  }
  if (tmp.empty()) refuse(parent, "cannot create a temporary directory");

  // Removes the temporary directory unless it was swapped in.
  struct Cleanup {
    fs::path path;
    ~Cleanup() {
      std::error_code ignored;
      if (!path.empty()) fs::remove_all(path, ignored);
    }
  } cleanup{tmp};

  const std::string marker = (tmp / kIncompleteMarker).string();
  std::map<std::string, Digest> files;
  bool exists = false;
  try {
    writeTextFile(marker, "written by " + tool + ", not finished\n");
    fill(tmp.string());
    files = collect(tmp, dir);
    // Again: the directory may have changed while `fill` ran.
    exists = checkTarget(target, dir, files, tool, replace);
    writeTextFile((tmp / kOwnedManifest).string(), manifestText(files, tool));
  } catch (const Error& e) {
    throw renamed(e, tmp.string(), dir);
  }
  fs::remove(marker, ec);
  if (ec) refuse(dir, "cannot finish the new output: " + ec.message());
  syncDirectory(tmp);

  if (exists) {
    exchange(tmp, target);  // tmp now holds the old output, removed by cleanup
  } else {
    if (::rename(tmp.c_str(), target.c_str()) != 0)
      refuse(dir, std::string("cannot create the directory: ") + std::strerror(errno));
    cleanup.path.clear();
  }
  syncDirectory(parent);
}

}  // namespace

void writeOwnedDirectory(const std::string& dir, const std::vector<OwnedFile>& files, const std::string& tool,
                         bool replace) {
  std::map<std::string, Digest> expected;
  for (const auto& f : files) {
    if (!isPlainRelative(f.first) || f.first == kOwnedManifest || f.first == kIncompleteMarker)
      throw Error("writing " + dir + ": '" + f.first + "' is not a file name inside the directory");
    expected[f.first] = digestOf(f.second);
  }
  writeOwned(
      dir, expected,
      [&](const std::string& tmp) {
        for (const auto& [rel, bytes] : files) {
          const fs::path file = fs::path(tmp) / rel;
          std::error_code ec;
          fs::create_directories(file.parent_path(), ec);
          if (ec) refuse(file.parent_path(), "cannot create the directory: " + ec.message());
          writeTextFile(file.string(), bytes);
        }
      },
      tool, replace);
}

void writeOwnedDirectory(const std::string& dir, const std::function<void(const std::string&)>& fill,
                         const std::string& tool, bool replace) {
  writeOwned(dir, {}, fill, tool, replace);
}

}  // namespace ddace::task
