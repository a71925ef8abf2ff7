// Draws the insert time of every scan of one or more builds from their reports (`bgkmap build
// --report`: timing.per_scan), against the scan's number: does the time per scan stay flat as the
// map grows? Each line is the median of a sliding window of scans (noise of a shared machine).
//
// Usage: plot_per_scan OUT.png TITLE WINDOW LABEL=REPORT.json [LABEL=REPORT.json ...]
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>
#include <vector>

#include "bgkmap/eval/plot.hpp"

int main(int argc, char** argv) {
  if (argc < 5) {
    std::fprintf(stderr, "usage: plot_per_scan OUT.png TITLE WINDOW LABEL=REPORT.json...\n");
    return 2;
  }
  try {
    const int window = std::max(1, std::atoi(argv[3]));
    bgkmap::eval::LinePanel panel;
    panel.title = "insert time per scan (median of " + std::to_string(window) + " scans)";
    panel.xlabel = "scan";
    panel.ylabel = "seconds";
    panel.y_min = 0;
    for (int a = 4; a < argc; ++a) {
      const std::string arg = argv[a];
      const size_t eq = arg.find('=');
      if (eq == std::string::npos) throw std::runtime_error(arg + ": expected LABEL=REPORT.json");
      std::ifstream in(arg.substr(eq + 1));
      if (!in) throw std::runtime_error(arg.substr(eq + 1) + ": cannot open");
      const std::vector<double> seconds = nlohmann::json::parse(in).at("timing").at("per_scan").get<std::vector<double>>();
      bgkmap::eval::LineSeries series;
      series.label = arg.substr(0, eq);
      for (size_t k = 0; k + window <= seconds.size(); k += window) {
        std::vector<double> w(seconds.begin() + k, seconds.begin() + k + window);
        std::nth_element(w.begin(), w.begin() + window / 2, w.end());
        series.x.push_back(static_cast<double>(k + window / 2));
        series.y.push_back(w[window / 2]);
      }
      panel.series.push_back(std::move(series));
    }
    bgkmap::eval::write_line_panels_png(argv[1], {panel}, 1, argv[2]);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "plot_per_scan: %s\n", e.what());
    return 1;
  }
  return 0;
}
