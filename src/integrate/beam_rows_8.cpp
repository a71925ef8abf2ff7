#include "integrate/beam_rows_8.hpp"

namespace bgkmap {

namespace {

BGK_CPU_CLONES void beam_row_masks_8_portable(const RowReach8& g, const LocalBeam* beams, size_t count,
                                              uint64_t* masks) {
  for (size_t i = 0; i < count; ++i) masks[i] = beam_row_mask_8(g, beams[i]);
}

#if BGK_AVX512_BEAMS
BGK_TARGET_AVX512 void beam_row_masks_8_avx512(const RowReach8& g, const LocalBeam* beams, size_t count,
                                               uint64_t* masks) {
  for (size_t i = 0; i < count; ++i) masks[i] = beam_row_mask_8_avx512(g, beams[i]);
}
#endif

}  // namespace

void beam_row_masks_8(const RowReach8& g, const LocalBeam* beams, size_t count, uint64_t* masks) {
#if BGK_AVX512_BEAMS
  if (cpu_runs_avx512_beams()) return beam_row_masks_8_avx512(g, beams, count, masks);
#endif
  beam_row_masks_8_portable(g, beams, count, masks);
}

#if BGK_AVX512_BEAMS
bool cpu_runs_avx512_beams() {
  // The condition under which the x86-64-v4 clones run.
  static const bool runs = __builtin_cpu_supports("x86-64-v4");
  return runs;
}
#endif

}  // namespace bgkmap
