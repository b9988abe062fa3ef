// CommandSources: see include/ddace/common/command_sources.h.
#include "ddace/common/command_sources.h"

#include <algorithm>

#include "ddace/common/error.h"

namespace ddace {

namespace {

std::string report(uint64_t count, const std::string& last) {
  return count == 0 ? "0" : std::to_string(count) + ", last from " + last;
}

}  // namespace

CommandSources::CommandSources(std::vector<std::string> allowed, const std::string& where)
    : allowed_(std::move(allowed)) {
  if (allowed_.empty())
    throw Error(where + " is empty: name the nodes that may command the wheels (e.g. [/path_follower, /coordinator])");
  for (const auto& n : allowed_)
    if (n.size() < 2 || n[0] != '/' || n.find_first_of(" \t\n") != std::string::npos)
      throw Error(where + " holds '" + n + "', not an absolute node name such as /path_follower");
}

CommandSources::Verdict CommandSources::check(const std::string& publisher, bool stamped) {
  if (std::find(allowed_.begin(), allowed_.end(), publisher) == allowed_.end()) {
    ++foreign_;
    last_foreign_ = publisher;
    return Verdict::Foreign;
  }
  if (!stamped) {
    ++unstamped_;
    last_unstamped_ = publisher;
    return Verdict::Unstamped;
  }
  return Verdict::Accepted;
}

std::string CommandSources::allowedList() const {
  std::string out;
  for (const auto& n : allowed_) out += (out.empty() ? "" : ", ") + n;
  return out;
}

std::string CommandSources::foreignReport() const {
  return report(foreign_, last_foreign_);
}

std::string CommandSources::unstampedReport() const {
  return report(unstamped_, last_unstamped_);
}

}  // namespace ddace
