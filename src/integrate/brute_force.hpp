// Plain reference for tests and checks: one cell against every observation in double precision,
// world coordinates, no bucketing (only a per-axis bounding-box early-out). Slow by design; the
// back ends are tested against it.
#pragma once

#include <vector>

#include "bgkmap/core/grid.hpp"
#include "bgkmap/core/params.hpp"
#include "bgkmap/integrate/observations.hpp"

namespace bgkmap {

struct BruteForcePosterior {
  double alpha = 0, beta = 0;
};

// Posterior of the cell centred at `center` (exact, see Grid::cell_center_d) after all `scans`
// (prior included); with `forget_half_life` (scans) > 0 the evidence decays toward the prior by
// 2^(-1/H) between consecutive scans, eagerly.
BruteForcePosterior brute_force_cell(const Vec3d& center, const std::vector<ScanObservations>& scans,
                                     const BuildParams& params, double forget_half_life = 0);

// The expected kernel's posterior: scan i's observations (world frame, as from the estimated
// pose) under the pose covariance covariances[i]: the sum over pose_sigma_points of weight times
// the kernel at the observations displaced by the point, displaced and evaluated in double (the
// rotation by its own quaternion arithmetic). A zero covariance adds the plain kernel. Sparse
// kernel only; on a planar map (params.preprocess.planar) the displaced z stays the plane's.
// Returns the posteriors of the cells centred at `centers`, in their order.
std::vector<BruteForcePosterior> brute_force_expected_cells(const std::vector<Vec3d>& centers,
                                                            const std::vector<ScanObservations>& scans,
                                                            const std::vector<PoseCovariance>& covariances,
                                                            const BuildParams& params);

// The expected sub-map's posterior (PoseFusion::kExpectedSubmap), from the same displaced
// observations in double: for each scan, the Beta(alpha0 + a_h, beta0 + b_h) of every sigma point
// h (a_h, b_h its plain counts) mixed with the point's weight, matched by its first two raw
// moments, and its counts beyond the prior (each at least 0) added; cells no point reaches are
// left alone. A zero covariance adds the plain counts.
std::vector<BruteForcePosterior> brute_force_expected_submap_cells(const std::vector<Vec3d>& centers,
                                                                   const std::vector<ScanObservations>& scans,
                                                                   const std::vector<PoseCovariance>& covariances,
                                                                   const BuildParams& params);

}  // namespace bgkmap
