#include "ddace/task/owned_dir.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <map>
#include <sstream>

#include "ddace/common/error.h"
#include "ddace/common/file.h"

namespace fs = std::filesystem;

namespace ddace::task {
namespace {

uint64_t fnv1a64(const std::string& bytes) {
  uint64_t h = 0xcbf29ce484222325ULL;
  for (unsigned char c : bytes) h = (h ^ c) * 0x100000001b3ULL;
  return h;
}

std::string hex16(uint64_t v) {
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(v));
  return buf;
}

struct Entry {
  uint64_t size = 0;
  std::string digest;  ///< 16 hex digits
};

/// The manifest's entries (relative path -> entry); false when it is not one we can read.
bool readManifest(const fs::path& file, std::map<std::string, Entry>& out) {
  std::string text;
  try {
    text = readTextFile(file.string());
  } catch (const Error&) {
    return false;
  }
  std::istringstream in(text);
  std::string line;
  if (!std::getline(in, line) || line.rfind("# ", 0) != 0) return false;
  while (std::getline(in, line)) {
    std::istringstream fields(line);
    Entry e;
    std::string path;
    if (!(fields >> e.digest >> e.size) || e.digest.size() != 16) return false;
    fields >> std::ws;
    std::getline(fields, path);
    if (path.empty()) return false;
    out[path] = e;
  }
  return true;
}

std::string manifestText(const std::vector<OwnedFile>& files, const std::string& tool) {
  std::string text = "# " + tool + " wrote these files (FNV-1a 64, bytes, path); it replaces only these\n";
  for (const auto& [path, bytes] : files)
    text += hex16(fnv1a64(bytes)) + " " + std::to_string(bytes.size()) + " " + path + "\n";
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

struct Survey {
  std::vector<std::string> foreign;  ///< "path (why)"
  size_t own = 0;                    ///< files that are the tool's own
};

/// Everything in `dir` judged as the tool's own or not (nothing is followed or opened
/// but regular files whose size matches a file we know).
Survey survey(const fs::path& dir, const fs::path& shown, const std::vector<OwnedFile>& incoming,
              const std::string& tool) {
  Survey s;
  std::map<std::string, Entry> manifest;
  const bool manifest_ok = readManifest(dir / kOwnedManifest, manifest);
  std::map<std::string, const std::string*> next;
  std::map<std::string, bool> parents;  // directories the tool's files live in
  auto addParents = [&](const std::string& rel) {
    for (fs::path p = fs::path(rel).parent_path(); !p.empty(); p = p.parent_path()) parents[p.generic_string()] = true;
  };
  for (const auto& f : incoming) {
    next[f.first] = &f.second;
    addParents(f.first);
  }
  if (manifest_ok)
    for (const auto& m : manifest) addParents(m.first);

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
      if (manifest_ok) ++s.own;
      else s.foreign.push_back(name + " (not a manifest " + tool + " can read)");
      continue;
    }
    const uint64_t size = fs::file_size(p, sec);
    const auto m = manifest_ok ? manifest.find(rel) : manifest.end();
    const auto n = next.find(rel);
    const bool may_be_listed = m != manifest.end() && !sec && m->second.size == size;
    const bool may_be_same = n != next.end() && !sec && n->second->size() == size;
    bool own = false;
    if (may_be_listed || may_be_same) {
      try {
        const std::string bytes = readTextFile(p.string());
        own = (may_be_listed && hex16(fnv1a64(bytes)) == m->second.digest) || (may_be_same && bytes == *n->second);
      } catch (const Error&) {
        own = false;
      }
    }
    if (own) ++s.own;
    else
      s.foreign.push_back(
          name + (m != manifest.end() ? " (changed since " + tool + " wrote it)" : " (not written by " + tool + ")"));
  }
  if (ec) s.foreign.push_back(shown.string() + " (cannot read the directory: " + ec.message() + ")");
  return s;
}

[[noreturn]] void refuse(const fs::path& path, const std::string& message) {
  throw Error(Diagnostic{path.string(), 0, 0, message});
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

}  // namespace

void writeOwnedDirectory(const std::string& dir, const std::vector<OwnedFile>& files, const std::string& tool,
                         bool replace) {
  for (const auto& f : files)
    if (!isPlainRelative(f.first) || f.first == kOwnedManifest)
      throw Error("writing " + dir + ": '" + f.first + "' is not a file name inside the directory");

  std::error_code ec;
  fs::path target = fs::absolute(fs::path(dir), ec).lexically_normal();
  if (!target.has_filename()) target = target.parent_path();
  if (ec || target == target.root_path()) refuse(dir, "cannot write into this directory");
  const fs::file_status st = fs::status(target, ec);
  bool exists = false;
  if (ec && st.type() != fs::file_type::not_found) refuse(dir, "cannot read: " + ec.message());
  if (fs::exists(st)) {
    if (!fs::is_directory(st)) refuse(dir, "exists and is not a directory");
    target = fs::canonical(target, ec);  // a symlink to a directory: replace the directory itself
    if (ec) refuse(dir, "cannot read: " + ec.message());
    const Survey s = survey(target, fs::path(dir), files, tool);
    if (!s.foreign.empty()) {
      std::string list;
      for (size_t i = 0; i < s.foreign.size() && i < 10; ++i) list += "\n  " + s.foreign[i];
      if (s.foreign.size() > 10) list += "\n  ... and " + std::to_string(s.foreign.size() - 10) + " more";
      refuse(dir, "refusing to write here: it holds " + std::to_string(s.foreign.size()) + " entr" +
                      (s.foreign.size() == 1 ? "y " : "ies ") + tool +
                      " did not write (move them away or choose another directory):" + list);
    }
    if (s.own > 0 && !replace) refuse(dir, "holds the output of an earlier " + tool + "; --force replaces it");
    exists = true;
  }

  const fs::path parent = target.parent_path();
  fs::create_directories(parent, ec);
  if (ec) refuse(parent, "cannot create the directory: " + ec.message());
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

  auto writeOne = [&](const std::string& rel, const std::string& bytes) {
    const fs::path file = tmp / rel;
    try {
      std::error_code dec;
      fs::create_directories(file.parent_path(), dec);
      if (dec)
        throw Error(Diagnostic{file.parent_path().string(), 0, 0, "cannot create the directory: " + dec.message()});
      writeTextFile(file.string(), bytes);
    } catch (const Error& e) {
      // Name the file as the user will look for it, not its temporary place.
      std::vector<Diagnostic> named;
      for (Diagnostic d : e.diagnostics()) {
        d.file = (fs::path(dir) / rel).string();
        named.push_back(d);
      }
      throw Error(named);
    }
  };
  for (const auto& [rel, bytes] : files) writeOne(rel, bytes);
  writeOne(kOwnedManifest, manifestText(files, tool));
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

}  // namespace ddace::task
