#include "integrate/beam_rows_8.hpp"

namespace bgkmap {

BGK_CPU_CLONES void beam_row_masks_8(const RowReach8& g, const LocalBeam* beams, size_t count, uint64_t* masks) {
  for (size_t i = 0; i < count; ++i) masks[i] = beam_row_mask_8(g, beams[i]);
}

#if BGK_AVX512_BEAMS
bool cpu_runs_avx512_beams() {
  static const bool runs = __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512bw") &&
                           __builtin_cpu_supports("avx512cd") && __builtin_cpu_supports("avx512dq") &&
                           __builtin_cpu_supports("avx512vl") && __builtin_cpu_supports("avx2") &&
                           __builtin_cpu_supports("bmi2") && __builtin_cpu_supports("fma");
  return runs;
}
#endif

}  // namespace bgkmap
