/* The records the host hands the OpenCL kernels, declared once for both (the kernels in kernels/
 * include this file, as they include bgk_math.h). Written in the common subset of C++17 and
 * OpenCL C 1.2: plain structs of 32-bit floats and unsigned ints, no padding, so a host array of
 * them is the device buffer byte for byte (the C++ side checks the sizes). */
#ifndef BGKMAP_CORE_BGK_LAYOUT_H
#define BGKMAP_CORE_BGK_LAYOUT_H

#ifdef __OPENCL_C_VERSION__
typedef uint bgk_uint;
#else
#include <cstdint>
typedef std::uint32_t bgk_uint;
#endif

/* A cell's Beta posterior parameters; the map's pool (host) and its device mirror. */
typedef struct {
  float alpha;
  float beta;
} BgkCell;

/* A hit as one block sees it: its position relative to the block's first cell centre, so that
 * cell (lx, ly, lz) sits at (lx, ly, lz) * resolution in the same frame. */
typedef struct {
  float x, y, z;
} BgkLocalHit;

/* A beam's free segment as one block sees it, for bgk_anchored_segment_dist2: an anchor on the
 * segment near the block (relative to the block's first cell centre), the unit direction, and
 * the segment's extent along it from the anchor. */
typedef struct {
  float qx, qy, qz;
  float ux, uy, uz;
  float s_min, s_max;
} BgkLocalBeam;

/* One block's observations of one scan in a launch: one work-group (or work-item) each. */
typedef struct {
  bgk_uint slot;                   /* the block's slot in the pool */
  bgk_uint hit_begin, hit_count;   /* into the launch's hits, in BgkLocalHit records */
  bgk_uint beam_begin, beam_count; /* into the launch's beams, in BgkLocalBeam records */
} BgkJob;

/* The records in floats, as the kernels stage them through local memory. */
#define BGK_HIT_FLOATS 3  /* BgkLocalHit: x y z */
#define BGK_BEAM_FLOATS 8 /* BgkLocalBeam: qx qy qz ux uy uz s_min s_max */

#ifndef __OPENCL_C_VERSION__
static_assert(sizeof(BgkCell) == 2 * sizeof(float), "BgkCell: two packed floats, as the device pool holds them");
static_assert(sizeof(BgkLocalHit) == BGK_HIT_FLOATS * sizeof(float), "BgkLocalHit: packed floats");
static_assert(sizeof(BgkLocalBeam) == BGK_BEAM_FLOATS * sizeof(float), "BgkLocalBeam: packed floats");
static_assert(sizeof(BgkJob) == 5 * sizeof(bgk_uint), "BgkJob: five packed uints");
#endif

#endif /* BGKMAP_CORE_BGK_LAYOUT_H */
