// The general parameters' table: each one's schema and its field in BuildParams.
#include "bgkmap/core/build_param_table.hpp"

#include "bgkmap/core/grid.hpp"

#include <limits>
#include "core/float_decimal.hpp"
#include "core/number_text.hpp"

namespace bgkmap {

namespace {

// A float field read as the shortest decimal that is the same float (0.2f is 0.2), as the report has it.
#define BGKMAP_FLOAT_FIELD(field)                                                      \
  [](const BuildParams& p) { return as_decimal(p.field); },                            \
      [](BuildParams& p, double v) { p.field = static_cast<float>(v); }, nullptr, nullptr
#define BGKMAP_DOUBLE_FIELD(field) \
  [](const BuildParams& p) { return p.field; }, [](BuildParams& p, double v) { p.field = v; }, nullptr, nullptr
#define BGKMAP_ENUM_FIELD(field, from_string)                                                   \
  nullptr, nullptr, [](const BuildParams& p) { return std::string(to_string(p.field)); }, \
      [](BuildParams& p, const std::string& v) { p.field = from_string(v); }

std::vector<BuildParam> make_table() {
  const BuildParams d;
  using S = ParamSpec;
  const double inf = std::numeric_limits<double>::infinity();
  const auto positive = [&](const char* key, double value, const char* help) {
    return S::number(key, value, above(0), below(inf), help);
  };
  return {
      {S::number("resolution", d.grid.resolution_m, at_least(kMinResolutionM), at_most(kMaxResolutionM), "Cell size")
           .in_unit("m")
           .with_note("32-bit cell keys of coordinates up to " + number_text(kCoordinateLimitM) + " m"),
       BGKMAP_DOUBLE_FIELD(grid.resolution_m)},
      {S::whole_number("block-depth", d.grid.block_depth, 1, 7, "Blocks hold 2^(depth-1) cells per side"),
       [](const BuildParams& p) { return double(p.grid.block_depth); },
       [](BuildParams& p, double v) { p.grid.block_depth = static_cast<int>(v); }, nullptr, nullptr},
      {S::choice("kernel", value_names<KernelType>(), to_string(d.kernel.type),
                 "sparse (BGK) or box (1 inside the cell: the counting sensor model)"),
       BGKMAP_ENUM_FIELD(kernel.type, kernel_type_from_string)},
      {positive("ell", as_decimal(d.kernel.ell_m), "Kernel length scale l").in_unit("m"), BGKMAP_FLOAT_FIELD(kernel.ell_m)},
      {positive("sigma0", as_decimal(d.kernel.sigma0), "Kernel scale"), BGKMAP_FLOAT_FIELD(kernel.sigma0)},
      {positive("prior-alpha", as_decimal(d.prior.alpha0), "Prior alpha0"), BGKMAP_FLOAT_FIELD(prior.alpha0)},
      {positive("prior-beta", as_decimal(d.prior.beta0), "Prior beta0"), BGKMAP_FLOAT_FIELD(prior.beta0)},
      {positive("ds", d.preprocess.downsample_m, "Voxel-grid downsampling leaf")
           .in_unit("m")
           .with_zero_meaning("off")
           .with_note("at least " + number_text(kMinDownsampleFraction) + " of --resolution"),
       BGKMAP_DOUBLE_FIELD(preprocess.downsample_m)},
      {positive("max-range", d.preprocess.max_range_m,
                "Returns farther than this add no hit, only a free beam of this length")
           .in_unit("m")
           .with_zero_meaning("no limit"),
       BGKMAP_DOUBLE_FIELD(preprocess.max_range_m)},
      {S::choice("beyond-range", value_names<BeyondRange>(), to_string(d.preprocess.beyond_range),
                 "Returns farther than --max-range: free (a free beam of max-range length, OctoMap's convention) "
                 "or drop (ignored, la3dm's)"),
       BGKMAP_ENUM_FIELD(preprocess.beyond_range, beyond_range_from_string)},
      {S::number("end-margin", d.preprocess.end_margin_m, at_least(0), below(inf),
                 "Free segments stop this far short of the hit")
           .in_unit("m"),
       BGKMAP_DOUBLE_FIELD(preprocess.end_margin_m)},
      {S::choice("kitti-frame", value_names<KittiFrame>(), to_string(d.preprocess.kitti_frame),
                 "The world of KITTI sequences: velodyne (the velodyne frame of the first scan, z up) or camera "
                 "(KITTI's camera-0 frame of the first scan, y down, z forward, as poses.txt)"),
       BGKMAP_ENUM_FIELD(preprocess.kitti_frame, kitti_frame_from_string)},
      {S::number("plane-z", d.preprocess.plane_z_m, above(-inf), below(inf),
                 "With --2d: a height in the layer of cells the map keeps")
           .in_unit("m"),
       BGKMAP_DOUBLE_FIELD(preprocess.plane_z_m)},
      {S::choice("pose-fusion", value_names<PoseFusion>(), to_string(d.preprocess.pose_fusion),
                 "How bgkl and bgk take a pose uncertainty: submap (each scan mapped under each sigma point of its "
                 "pose, the moment-matched mixture of those sub-maps added) or kernel (the kernel averaged over the "
                 "sigma points); gpom and wgpom: submap (one sub-map per sigma point, every uncertain scan under its "
                 "own, the cells' predictions moment matched) or kernel (each training input a Gaussian position "
                 "from the sigma points, the GP's covariances their expectations)"),
       BGKMAP_ENUM_FIELD(preprocess.pose_fusion, pose_fusion_from_string)},
      {S::number("occupied-threshold", as_decimal(d.classify.occupied_threshold), at_least(0), at_most(1),
                 "Mean above which a cell is occupied"),
       BGKMAP_FLOAT_FIELD(classify.occupied_threshold)},
      {S::number("free-threshold", as_decimal(d.classify.free_threshold), at_least(0), at_most(1),
                 "Mean below which a cell is free (at most --occupied-threshold)"),
       BGKMAP_FLOAT_FIELD(classify.free_threshold)},
      {positive("var-threshold", as_decimal(d.classify.var_threshold), "Variance above which a cell is unknown"),
       BGKMAP_FLOAT_FIELD(classify.var_threshold)},
  };
}

#undef BGKMAP_FLOAT_FIELD
#undef BGKMAP_DOUBLE_FIELD
#undef BGKMAP_ENUM_FIELD

}  // namespace

void BuildParam::set(BuildParams& params, double value) const {
  if (!spec.accepts(value)) throw rejection(spec);
  set_number(params, value);
}

void BuildParam::set(BuildParams& params, const std::string& value) const {
  if (!spec.accepts(value)) throw rejection(spec, value);
  set_name(params, value);
}

const std::vector<BuildParam>& build_param_table() {
  static const std::vector<BuildParam> table = make_table();
  return table;
}

const BuildParam* find_build_param(const std::string& key) {
  const std::string flag = param_key(key);
  for (const BuildParam& p : build_param_table())
    if (p.spec.key == flag) return &p;
  return nullptr;
}

}  // namespace bgkmap
