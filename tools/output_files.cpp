#include "output_files.h"

#include <spdlog/spdlog.h>
#include <unistd.h>

#include <filesystem>
#include <fmt/format.h>
#include <fstream>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "strut/daq/atomic_file.h"

namespace strut::tools {
namespace fs = std::filesystem;
namespace {

bool IsHdf5File(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  char signature[8] = {};
  in.read(signature, 8);
  return in && std::string(signature, 8) == "\x89HDF\r\n\x1a\n";
}

}  // namespace

void CheckOutputPath(const std::string& option, const std::string& path, const std::vector<std::string>& inputs,
                     bool force) {
  if (path.empty()) return;
  std::error_code ec;
  const fs::path target(path);
  for (const std::string& input : inputs)
    if (fs::exists(target, ec) && fs::equivalent(target, fs::path(input), ec))
      throw std::invalid_argument(fmt::format("{} {}: that is an input of this command; it would be overwritten", option, path));
  if (fs::is_directory(target, ec)) throw std::invalid_argument(fmt::format("{} {}: is a directory", option, path));
  if (fs::exists(target, ec) && IsHdf5File(target) && !force)
    throw std::invalid_argument(
        fmt::format("{} {}: an HDF5 file (a session?) exists there; choose another name or add --force to replace it",
                    option, path));
  const fs::path folder = target.has_parent_path() ? target.parent_path() : fs::path(".");
  if (!fs::is_directory(folder, ec))
    throw std::invalid_argument(fmt::format("{} {}: the folder {} does not exist", option, path, folder.string()));
  if (access(folder.c_str(), W_OK) != 0)
    throw std::invalid_argument(fmt::format("{} {}: the folder {} is not writable", option, path, folder.string()));
}

void WriteTextOutput(const std::string& path, const std::string& text) {
  daq::WriteFileAtomically(path, text);
  spdlog::info("wrote {}", path);
}

void WriteJsonOutput(const std::string& path, const nlohmann::json& json) { WriteTextOutput(path, json.dump(1) + "\n"); }

}  // namespace strut::tools
