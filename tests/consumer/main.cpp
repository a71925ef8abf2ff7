// Maps one beam with the core library, writes and reads back the native map, and checks what a
// user would: the hit's cell occupied, the cells along the beam free, the file round trip exact.
#include <bgkmap/integrate/backend.hpp>
#include <bgkmap/io/native_map.hpp>
#include <bgkmap/mapper.hpp>

#include <cstdio>
#include <filesystem>

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: consumer MAP.bgk\n");
    return 2;
  }
  bgkmap::BuildParams params;
  bgkmap::BackendOptions backend;
  backend.backend = "cpu";
  bgkmap::Mapper mapper(params, bgkmap::make_integrator(backend));
  bgkmap::Scan scan;
  scan.pose.position = {0.05f, 0.05f, 0.05f};
  for (int i = 0; i < 20; ++i) scan.points.push_back({2.05f, 0.05f, 0.05f});
  mapper.insert(scan);
  const bgkmap::BgkMap& map = mapper.map();
  const bgkmap::CellPosterior hit = map.query(2.05, 0.05, 0.05), free = map.query(1.05, 0.05, 0.05);
  std::printf("hit cell: mean %.4f, beam cell: mean %.4f\n", hit.mean(), free.mean());
  if (!(hit.mean() > params.classify.occupied_threshold) || !(free.mean() < params.classify.free_threshold)) return 1;

  bgkmap::write_native_map(argv[1], map);
  const bgkmap::BgkMap back = bgkmap::read_native_map(argv[1]);
  const bgkmap::CellPosterior read_hit = back.query(2.05, 0.05, 0.05);
  if (read_hit.alpha != hit.alpha || read_hit.beta != hit.beta || back.block_count() != map.block_count()) return 1;
  std::printf("consumer: ok (%zu blocks)\n", back.block_count());
  return 0;
}
