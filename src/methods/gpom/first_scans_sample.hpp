// gpom's paper mode: the training set its hyper-parameters are learned on, drawn at random from
// the first scans' hits and beams (IJRR sec. 3.2: "randomly sampling the first few initial scans
// ... occupied points and free space points obtained by discretizing the sensor beams").
#pragma once

#include <cstddef>
#include <cstdint>

#include "methods/gp/gp_regression.hpp"
#include "methods/gpom/training_set.hpp"

namespace bgkmap::gpom {

// How much of the training data the first scans hold: its first `hits` hits and `beams` beams.
struct FirstScans {
  size_t hits = 0, beams = 0;
};

// `points` inputs from `first` of `set` (the same seed, the same draw): half (rounded up) distinct
// hits, label +1; the rest, points of distinct beams at a uniform fraction along each, label -1.
// Fewer hits or beams than asked: all of them.
LocalModel first_scans_sample(const TrainingData& set, const FirstScans& first, size_t points, uint64_t seed);

}  // namespace bgkmap::gpom
