// A float parameter as the shortest decimal that reads back as the same float (0.2f -> 0.2,
// not 0.20000000298023224), so reports and `info` show what the user typed.
#pragma once

#include <charconv>
#include <cstdlib>
#include <string>

namespace bgkmap {

inline double as_decimal(float value) {
  char text[32];
  const auto result = std::to_chars(text, text + sizeof text, value);
  return std::strtod(std::string(text, result.ptr).c_str(), nullptr);
}

}  // namespace bgkmap
