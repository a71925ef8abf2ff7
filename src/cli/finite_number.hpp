// A flag's check that its value is a finite number ("nan" would read as a flag's unset default,
// "inf" as no value at all): `--z inf is not a finite height`.
#pragma once

#include <CLI/CLI.hpp>

#include <cmath>
#include <cstdlib>
#include <string>

namespace bgkmap::cli {

// `what` names the quantity in the refusal ("height"); the type name is shown in --help.
inline CLI::Validator finite_number(const std::string& flag, const std::string& what, const std::string& type_name) {
  return CLI::Validator(
      [flag, what](std::string& text) {
        char* end = nullptr;
        const double v = std::strtod(text.c_str(), &end);
        return end != text.c_str() && *end == '\0' && std::isfinite(v) ? std::string()
                                                                        : flag + " " + text + " is not a finite " + what;
      },
      type_name);
}

}  // namespace bgkmap::cli
