// The whole text of a file the batch wrote itself (a record, the plan, the job list), "" when it is
// not there yet.
#pragma once

#include <fstream>
#include <sstream>
#include <string>

namespace strut::batch {

inline std::string ReadText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

}  // namespace strut::batch
