#include "ddace/common/file.h"

#include <fstream>
#include <sstream>

#include "ddace/common/error.h"

namespace ddace {

std::string readTextFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(Diagnostic{path, 0, 0, "cannot open file"});
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

}  // namespace ddace
