// What an output flag's name may end in: a command writes one kind of file, and a name of another
// kind (view -o map.png, an HTML page) is refused as a usage error before any work is done.
#pragma once

#include <CLI/CLI.hpp>

#include <string>
#include <vector>

namespace bgkmap::cli {

// `extensions` in lower case with their dot (".png"); `writes` says what, e.g. "render writes a
// PNG image". The case of the name's extension does not matter.
CLI::Validator output_extension(std::vector<std::string> extensions, const std::string& writes);
// A map format's extension (.bgk, .ot, .bt, or an export: .pgm, .ply, .pcd).
CLI::Validator map_output_extension();
// An HTML page's extension (.html, .htm): what view writes.
CLI::Validator view_output_extension();
// An export's extension (.pgm, .ply, .pcd).
CLI::Validator export_output_extension();

}  // namespace bgkmap::cli
