// A number as messages show it: printf's %g (0.1, 1e+06, 3.14159); and as `info` shows a computed
// one: its 15 significant digits, without the binary rounding of the arithmetic behind it.
#pragma once

#include <cstdio>
#include <cstdlib>
#include <string>

namespace bgkmap {

inline std::string number_text(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%g", v);
  return text;
}

// 15 significant digits are what a double holds of any decimal: a cell centre (-2 + 0.5) * 0.1 is
// -0.15, not -0.15000000000000002.
inline std::string decimal_text(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%.15g", v);
  return text;
}

// The double nearest decimal_text(v), which JSON then writes as that text.
inline double decimal_value(double v) { return std::strtod(decimal_text(v).c_str(), nullptr); }

}  // namespace bgkmap
