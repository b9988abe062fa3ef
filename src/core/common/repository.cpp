#include "ddace/common/repository.h"

#include <cstdlib>
#include <sstream>
#include <system_error>

#include "ddace/common/error.h"
#include "ddace/common/file.h"

namespace ddace {
namespace {

namespace fs = std::filesystem;

// The text of the first <name> element outside comments, trimmed ("" when there is none).
std::string packageName(const std::string& xml) {
  std::string text;
  for (std::size_t at = 0; at < xml.size();) {
    const std::size_t open = xml.find("<!--", at);
    text.append(xml, at, open == std::string::npos ? std::string::npos : open - at);
    if (open == std::string::npos) break;
    const std::size_t close = xml.find("-->", open + 4);
    if (close == std::string::npos) break;
    at = close + 3;
  }
  const std::size_t begin = text.find("<name>");
  if (begin == std::string::npos) return "";
  const std::size_t end = text.find("</name>", begin);
  if (end == std::string::npos) return "";
  std::string name = text.substr(begin + 6, end - begin - 6);
  const auto first = name.find_first_not_of(" \t\r\n");
  const auto last = name.find_last_not_of(" \t\r\n");
  return first == std::string::npos ? "" : name.substr(first, last - first + 1);
}

// The directory package.xml really lives in (through a symlink farm to the repository).
fs::path resolved(const fs::path& dir) {
  std::error_code ec;
  const fs::path real = fs::canonical(dir / "package.xml", ec);
  return ec ? fs::absolute(dir) : real.parent_path();
}

// The first of `needs` that `dir` lacks ("" when it has them all).
std::string missing(const fs::path& dir, const std::vector<std::string>& needs) {
  for (const auto& n : needs) {
    std::error_code ec;
    if (!fs::exists(dir / n, ec)) return n;
  }
  return "";
}

// Packages in `dir` and up to `depth` levels below it (not below a package: rospack's rule).
void packagesUnder(const fs::path& dir, int depth, std::vector<fs::path>& out) {
  if (isDdacePackage(dir)) {
    out.push_back(dir);
    return;
  }
  std::error_code ec;
  if (depth == 0 || fs::exists(dir / "package.xml", ec)) return;
  fs::directory_iterator it(dir, ec), end;
  for (; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    std::error_code dir_ec;
    if (!name.empty() && name[0] != '.' && it->is_directory(dir_ec)) packagesUnder(it->path(), depth - 1, out);
  }
}

}  // namespace

bool isDdacePackage(const fs::path& dir) {
  try {
    return packageName(readTextFile((dir / "package.xml").string(), 1 << 20)) == "ddace";
  } catch (const Error&) {
    return false;  // no manifest, not a regular file, unreadable: not this package
  }
}

fs::path locateRepository(const RepositorySearch& search) {
  std::string needs_text;
  for (const auto& n : search.needs) needs_text += (needs_text.empty() ? "" : ", ") + n;

  // `given` names the setting in messages: "--repo DIR" or "DDACE_REPO=DIR".
  auto explicitly = [&](const std::string& dir, const std::string& given) {
    if (!isDdacePackage(dir))
      throw Error(given + ": not the ddace package directory (no package.xml with <name>ddace</name>)");
    const fs::path found = resolved(dir);
    const std::string lacks = missing(found, search.needs);
    if (!lacks.empty()) throw Error(given + ": the ddace package there has no " + lacks);
    return found;
  };
  if (!search.explicit_dir.empty())
    return explicitly(search.explicit_dir, search.explicit_what + " " + search.explicit_dir);
  if (!search.env_dir.empty()) return explicitly(search.env_dir, std::string(kRepositoryEnv) + "=" + search.env_dir);

  std::vector<std::string> skipped;  // ddace packages that lack something, for the message
  auto accept = [&](const fs::path& dir) {
    const fs::path found = resolved(dir);
    const std::string lacks = missing(found, search.needs);
    if (lacks.empty()) return true;
    skipped.push_back(found.string() + " (no " + lacks + ")");
    return false;
  };
  for (const auto& start : search.walk_from) {
    if (start.empty()) continue;
    for (fs::path dir = fs::absolute(start);; dir = dir.parent_path()) {
      if (isDdacePackage(dir) && accept(dir)) return resolved(dir);
      if (isDdacePackage(dir / "share" / "ddace") && accept(dir / "share" / "ddace"))
        return resolved(dir / "share" / "ddace");
      if (dir == dir.root_path() || dir.empty()) break;
    }
  }
  std::stringstream entries(search.ros_package_path);
  for (std::string entry; std::getline(entries, entry, ':');) {
    if (entry.empty()) continue;
    std::vector<fs::path> found;
    packagesUnder(entry, 2, found);
    for (const auto& dir : found)
      if (accept(dir)) return resolved(dir);
  }

  std::string message = "cannot find the ddace package directory";
  if (!needs_text.empty()) message += " with " + needs_text;
  message += ": looked in";
  for (const auto& start : search.walk_from)
    if (!start.empty()) message += " " + start + " and its parents,";
  message += " $ROS_PACKAGE_PATH (" + (search.ros_package_path.empty() ? "unset" : search.ros_package_path) + ")";
  if (!skipped.empty()) {
    message += "; skipped";
    for (const auto& s : skipped) message += " " + s;
  }
  message += ". Pass " + search.explicit_what + " DIR or set " + kRepositoryEnv + "=DIR (the repository's root).";
  throw Error(message);
}

fs::path findRepository(const std::string& explicit_dir, const std::vector<std::string>& needs) {
  RepositorySearch s;
  s.explicit_dir = explicit_dir;
  if (const char* env = std::getenv(kRepositoryEnv)) s.env_dir = env;
  std::error_code ec;
  const fs::path cwd = fs::current_path(ec);
  if (!ec) s.walk_from.push_back(cwd.string());
  const fs::path self = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) s.walk_from.push_back(self.parent_path().string());
  if (const char* rpp = std::getenv("ROS_PACKAGE_PATH")) s.ros_package_path = rpp;
  s.needs = needs;
  return locateRepository(s);
}

}  // namespace ddace
