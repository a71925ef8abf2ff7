// The viewer page's HTML, CSS and WebGL code, with the map's data put in.
#pragma once

#include <string>

namespace bgkmap::viz {

// meta_json: the map's description (see write_view_html); positions / info: base64 of the boxes.
std::string view_page(const std::string& meta_json, const std::string& positions_base64,
                      const std::string& info_base64);

}  // namespace bgkmap::viz
