#include "cli/output_names.hpp"

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <utility>

#include "bgkmap/io/errors.hpp"
#include "bgkmap/io/map_io.hpp"

namespace bgkmap::cli {

namespace {
std::string lower_extension(const std::string& name) {
  std::string ext = std::filesystem::path(name).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext;
}
}  // namespace

CLI::Validator output_extension(std::vector<std::string> extensions, const std::string& writes) {
  std::string listed;
  for (size_t i = 0; i < extensions.size(); ++i)
    listed += (i == 0 ? "" : i + 1 == extensions.size() ? " or " : ", ") + extensions[i];
  return CLI::Validator(
      [extensions = std::move(extensions), message = writes + "; give a name ending in " + listed](std::string& name) {
        const std::string ext = lower_extension(name);
        if (std::find(extensions.begin(), extensions.end(), ext) != extensions.end()) return std::string();
        return name + ": " + message;
      },
      "");
}

CLI::Validator map_output_extension() {
  return CLI::Validator(
      [](std::string& name) {
        try {
          map_format_from_path(name);
          return std::string();
        } catch (const InputError& e) {
          return std::string(e.what());
        }
      },
      "");
}

CLI::Validator view_output_extension() { return output_extension({".html", ".htm"}, "view writes an HTML page"); }

CLI::Validator export_output_extension() {
  return output_extension({".pgm", ".ply", ".pcd"},
                          "export writes a ROS map_server grid or a cloud of occupied cells (a .bgk, .ot or .bt comes "
                          "from build or merge)");
}

}  // namespace bgkmap::cli
