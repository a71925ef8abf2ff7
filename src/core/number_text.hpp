// A number as messages show it: printf's %g (0.1, 1e+06, 3.14159).
#pragma once

#include <cstdio>
#include <string>

namespace bgkmap {

inline std::string number_text(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%g", v);
  return text;
}

}  // namespace bgkmap
