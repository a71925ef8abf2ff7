// How far a long phase has come, reported to a callback the caller supplies: the library prints
// nothing, so the CLI draws a bar and Python can pass its own function.
#pragma once

#include <cstdint>
#include <functional>
#include <string>

namespace bgkmap {

struct Progress {
  std::string phase;  // what is being done: "build", "gpom prediction", "score", ...
  std::string unit;   // what done and total count: "scans", "blocks", "cells", "gammas"
  uint64_t done = 0;
  uint64_t total = 0;      // 0: not known
  bool estimated = false;  // total is an estimate (a log's scans from its bytes read so far)
};

// Called from one thread at a time, maybe often: it should be cheap (or throttle itself).
using ProgressCallback = std::function<void(const Progress&)>;

}  // namespace bgkmap
