// Scoring a map of a dynamic scene (sim/dynamic.hpp) at time t, cell by what happened in it:
//   static cells   every cell no dynamic object ever covers (at any scan of the run): the
//                  structure a map should keep whatever moves
//   vacated cells  cells a dynamic object covered at some scan before t and nothing covers at t,
//                  since seen through: a beam of a later scan (true pose, no noise, cast into
//                  the scene at that scan) passed through the cell before ending. "removed" when
//                  the object that last covered it stands still (a door, a parked car), "trail"
//                  when it moves (a walker)
// A cell is covered when its centre lies inside the object, as the truth's cells.
#pragma once

#include <cstdint>
#include <memory>
#include <unordered_map>
#include <vector>

#include "bgkmap/core/grid.hpp"
#include "bgkmap/eval/truth.hpp"
#include "bgkmap/sim/spec.hpp"

namespace bgkmap::eval {

struct VacatedScores {
  uint64_t cells = 0;            // vacated and seen through by time t
  uint64_t read_free = 0;        // of them, scoring below the free threshold
  uint64_t read_occupied = 0;    // of them, scoring above the occupied threshold
  uint64_t settled_cells = 0;    // seen through at least kSettleScans scans before t (seen at t - 3 or earlier)
  uint64_t settled_free = 0;     // of them, reading free
};

// "Reads free within 3 scans of being seen through": the settled cells.
constexpr int kSettleScans = 3;

struct DynamicScores {
  VacatedScores removed, trail;
};

class DynamicCells {
 public:
  // Every cell of `grid` any dynamic object of spec.scene covers at a scan of the trajectory.
  DynamicCells(const sim::SimulationSpec& spec, const Grid& grid);

  // Takes scan next_scan() into account (what it covers, what its beams see through).
  void advance();
  // The scans taken into account so far: the time scored is next_scan() - 1.
  int next_scan() const { return next_scan_; }
  size_t size() const { return cells_.size(); }
  bool is_dynamic(const CellIndex& c) const { return cells_.count(key(c)) > 0; }

  // The vacated cells at time next_scan() - 1 as `sample` scores them.
  DynamicScores score(const MapSampler& sample, double free_threshold, double occupied_threshold) const;

 private:
  struct Track {
    CellIndex index;
    int last_covered = -1;  // scan; -1: not covered yet
    int seen_through = -1;  // first scan after last_covered whose beams pass through it; -1: none yet
    bool covered_now = false;
    bool by_walker = false;  // the object that last covered it moves
  };
  static uint64_t key(const CellIndex& c);
  void mark_seen_through(int scan, const sim::Scene& now);

  const sim::SimulationSpec& spec_;
  Grid grid_;
  std::vector<Pose> poses_;
  std::vector<Vec3d> directions_;
  std::unordered_map<uint64_t, Track> cells_;
  sim::Box3d bounds_;  // of every dynamic cell
  int next_scan_ = 0;
};

// `truth` with every dynamic cell left unknown: scores the static cells only.
std::unique_ptr<Truth> static_cells_truth(const Truth& truth, const DynamicCells& dynamic);

}  // namespace bgkmap::eval
