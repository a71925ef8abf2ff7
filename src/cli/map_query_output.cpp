#include "cli/map_query_output.hpp"

#include <cstdio>
#include <filesystem>
#include <stdexcept>
#include <vector>

#include "bgkmap/io/errors.hpp"
#include "io/text_lines.hpp"

namespace bgkmap::cli {

void print_cell_line(const Vec3d& c, const CellPosterior& post, CellState state) {
  std::printf("%.9g %.9g %.9g %.9g %.9g %.9g %.9g %s\n", c.x, c.y, c.z, post.alpha, post.beta, post.mean(),
              post.variance(), to_string(state));
}

void print_ray_casts(const BgkMap& map, const std::string& rays_file, UnknownPolicy policy) {
  const std::filesystem::path file = std::filesystem::path(rays_file == "-" ? "/dev/stdin" : rays_file);
  if (std::filesystem::is_directory(file)) throw InputError(file, "is a folder, not a file of rays");
  io_detail::TextLines lines(file);
  const RayCaster caster(map);
  std::string line;
  while (lines.next(line)) {
    const std::vector<std::string_view> fields = io_detail::split_fields(line);
    if (fields.empty() || fields.front().front() == '#') continue;
    double v[7] = {0, 0, 0, 0, 0, 0, 0};
    bool ok = fields.size() == 6 || fields.size() == 7;
    for (size_t i = 0; ok && i < fields.size(); ++i) ok = io_detail::parse_number(fields[i], v[i]);
    if (!ok) lines.fail("expected 'ox oy oz dx dy dz [max_range]', got '" + io_detail::excerpt(line) + "'");
    RayCast ray;
    try {
      ray = caster.cast({v[0], v[1], v[2]}, {v[3], v[4], v[5]}, v[6], policy);
    } catch (const std::invalid_argument& e) {
      lines.fail(std::string(e.what()) + " ('" + io_detail::excerpt(line) + "')");
    }
    std::printf("%d %.9g %.9g %.9g %.9g %s %s\n", ray.hit() ? 1 : 0, ray.center.x, ray.center.y, ray.center.z,
                ray.distance, to_string(ray.state), to_string(ray.stop));
  }
}

void print_cells_in_box(const BgkMap& map, const CellBox* box, CellSelection selection) {
  for_each_cell_in_box(map, box, selection,
                       [](const MapCell& cell) { print_cell_line(cell.center, cell.posterior, cell.state); });
}

}  // namespace bgkmap::cli
