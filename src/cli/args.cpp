#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>

#include "command.h"
#include "ddace/common/error.h"

namespace ddace::cli {

std::map<std::string, Command>& commands() {
  static std::map<std::string, Command> registry;
  return registry;
}

namespace {

/// Edits (insert, delete, replace, swap two neighbours) that turn `a` into `b`.
size_t editDistance(const std::string& a, const std::string& b) {
  std::vector<std::vector<size_t>> d(a.size() + 1, std::vector<size_t>(b.size() + 1));
  for (size_t i = 0; i <= a.size(); ++i) d[i][0] = i;
  for (size_t j = 0; j <= b.size(); ++j) d[0][j] = j;
  for (size_t i = 1; i <= a.size(); ++i)
    for (size_t j = 1; j <= b.size(); ++j) {
      d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1)});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1])
        d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
    }
  return d[a.size()][b.size()];
}

}  // namespace

std::string didYouMean(const std::string& word, const std::vector<std::string>& candidates) {
  // A slip, not another word: at most two edits, and fewer than a third of the word's letters.
  const size_t allowed = std::min<size_t>(2, std::max<size_t>(1, word.size() / 3));
  std::string best;
  size_t best_d = allowed + 1;
  for (const auto& c : candidates) {
    const size_t d = editDistance(word, c);
    if (d < best_d) best = c, best_d = d;
  }
  return best.empty() ? "" : " (did you mean " + best + "?)";
}

Registrar::Registrar(Command command) {
  commands()[command.name] = std::move(command);
}

Args::Args(const std::vector<std::string>& argv, const std::vector<std::string>& options,
           const std::vector<std::string>& switches) {
  auto contains = [](const std::vector<std::string>& v, const std::string& s) {
    return std::find(v.begin(), v.end(), s) != v.end();
  };
  for (size_t i = 0; i < argv.size(); ++i) {
    const std::string& a = argv[i];
    if (a.size() > 2 && a.compare(0, 2, "--") == 0) {
      std::string flag = a, value;
      const auto eq = a.find('=');
      const bool inline_value = eq != std::string::npos;
      if (inline_value) {
        flag = a.substr(0, eq);
        value = a.substr(eq + 1);
      }
      if (contains(switches, flag)) {
        if (inline_value) throw Error("option " + flag + " takes no value");
        values_[flag] = "1";
      } else if (contains(options, flag)) {
        if (!inline_value) {
          if (i + 1 >= argv.size()) throw Error("option " + flag + " needs a value");
          value = argv[++i];
        }
        values_[flag] = value;
      } else {
        std::vector<std::string> known = options;
        known.insert(known.end(), switches.begin(), switches.end());
        throw Error("unknown option " + flag + didYouMean(flag, known));
      }
    } else {
      positional_.push_back(a);
    }
  }
}

std::string Args::positional(size_t i, const std::string& what) const {
  if (i >= positional_.size()) throw Error("missing argument " + what);
  return positional_[i];
}

void Args::expectAtMostPositional(size_t n) const {
  if (positional_.size() > n) throw Error("unexpected argument '" + positional_[n] + "'");
}

bool Args::has(const std::string& flag) const {
  return values_.count(flag) > 0;
}

std::string Args::get(const std::string& flag, const std::string& fallback) const {
  auto it = values_.find(flag);
  return it == values_.end() ? fallback : it->second;
}

std::string Args::require(const std::string& flag) const {
  auto it = values_.find(flag);
  if (it == values_.end()) throw Error("missing required option " + flag);
  return it->second;
}

long Args::getInt(const std::string& flag, long fallback) const {
  if (!has(flag)) return fallback;
  const std::string s = get(flag, "");
  char* end = nullptr;
  errno = 0;
  const long v = std::strtol(s.c_str(), &end, 10);
  if (s.empty() || *end != '\0' || errno != 0) throw Error("option " + flag + ": '" + s + "' is not an integer");
  return v;
}

double Args::getDouble(const std::string& flag, double fallback) const {
  if (!has(flag)) return fallback;
  const std::string s = get(flag, "");
  char* end = nullptr;
  const double v = std::strtod(s.c_str(), &end);
  if (s.empty() || *end != '\0' || !std::isfinite(v))
    throw Error("option " + flag + ": '" + s + "' is not a finite number");
  return v;
}

std::string unlabelledAdvice(const std::string& dir, bool all) {
  if (all) return "`ddace label " + dir + " --out DIR` infers their labels (then train on DIR)";
  return "`ddace label " + dir +
         " --out DIR` infers their labels and copies the labelled demonstrations as they are (then train on DIR)";
}

}  // namespace ddace::cli
