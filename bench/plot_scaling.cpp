// Draws docs/img/bench_scaling.png from bench_scaling's JSON output (--benchmark_out): insert time
// per scan against points per scan (left) and against max range (right), one line per method,
// through the eval module's line-plot helper (bgkmap::eval::write_line_panels_png).
//
// Usage: plot_scaling OUT.png RESULTS.json [MORE.json ...]
// Takes each run's median when the JSON holds aggregates (--benchmark_repetitions), else the mean
// of its repetitions. Several files can be given (e.g. the two sweeps run separately with
// --benchmark_filter, each in a quiet spell of a shared machine); a run in a later file replaces
// the same run in an earlier one. The labels come from the first file's context. The line-plot helper has logarithmic y axes only, so points per scan are
// drawn on a log10 scale by plotting log10(points) (the axis label says so).
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <map>
#include <nlohmann/json.hpp>
#include <regex>
#include <stdexcept>
#include <string>
#include <tuple>
#include <vector>

#include "bgkmap/eval/plot.hpp"

namespace {

double seconds_of(double value, const std::string& unit) {
  if (unit == "ns") return value * 1e-9;
  if (unit == "us") return value * 1e-6;
  if (unit == "ms") return value * 1e-3;
  if (unit == "s") return value;
  throw std::runtime_error("unknown time_unit '" + unit + "'");
}

struct Run {
  std::string family, method;  // "BM_PointsPerScan" / "BM_MaxRange", "cpu" / "opencl" / "octomap"
  double x = 0;                // the argument: points or metres
  std::vector<double> seconds;  // the iterations' entries (no aggregates)
  double median = std::nan("");  // the median aggregate, when there is one
};

// "BM_PointsPerScan/cpu/points:1024/manual_time" -> family, method, 1024.
bool parse_run_name(const std::string& name, Run& run) {
  const size_t a = name.find('/'), b = name.find('/', a + 1), colon = name.find(':', b + 1);
  if (a == std::string::npos || b == std::string::npos || colon == std::string::npos) return false;
  run.family = name.substr(0, a);
  run.method = name.substr(a + 1, b - a - 1);
  run.x = std::stod(name.substr(colon + 1));
  return true;
}

// The number just before `unit` in `text` ("2" from "..., 2 OpenMP threads"), or "".
std::string count_before(const std::string& text, const std::string& unit) {
  const size_t end = text.find(unit);
  if (end == std::string::npos || end == 0) return "";
  size_t begin = end;
  while (begin > 0 && std::isdigit(static_cast<unsigned char>(text[begin - 1]))) --begin;
  return text.substr(begin, end - begin);
}

std::string plural(const std::string& count, const std::string& noun) {
  return count + " " + noun + (count == "1" ? "" : "s");
}

std::string label_of(const std::string& method, const nlohmann::json& context) {
  if (method == "cpu") {
    const std::string threads = count_before(context.value("cpu_backend", std::string()), " OpenMP threads");
    return "BGK-L, CPU back end (OpenMP" + (threads.empty() ? "" : ", " + plural(threads, "thread")) + ")";
  }
  if (method == "opencl") {
    // "Portable Computing Language / pthread-... (CPU, 2 compute units, ...)" -> platform, units
    const std::string device = context.value("opencl_backend", std::string());
    const std::string units = count_before(device, " compute units");
    return "BGK-L, OpenCL back end (" + device.substr(0, device.find(" / ")) +
           (units.empty() ? "" : ", " + plural(units, "compute unit")) + ")";
  }
  if (method == "octomap") return "OctoMap insertPointCloud (single thread)";
  return method;
}

// Legend order: the back ends, then OctoMap, then anything else.
int method_rank(const std::string& method) {
  return method == "cpu" ? 0 : method == "opencl" ? 1 : method == "octomap" ? 2 : 3;
}

// One benchmark JSON file. Google Benchmark writes counters it cannot compute (the cv of a
// counter that is always 0) as bare NaN / -nan / Infinity, which is not JSON: read as null.
nlohmann::json read_results(const std::string& file) {
  std::ifstream in(file);
  if (!in) throw std::runtime_error(file + ": cannot open");
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string cleaned = std::regex_replace(text, std::regex(R"(:\s*-?(nan|NaN|inf|Infinity)\b)"), ": null");
  try {
    nlohmann::json results = nlohmann::json::parse(cleaned);
    if (!results.contains("benchmarks") || !results["benchmarks"].is_array())
      throw std::runtime_error(file + ": no \"benchmarks\" array (not --benchmark_out JSON)");
    return results;
  } catch (const nlohmann::json::exception& e) {
    throw std::runtime_error(file + ": not benchmark JSON (" + e.what() + ")");
  }
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: %s OUT.png RESULTS.json [MORE.json ...]\n", argv[0]);
    return 2;
  }
  try {
    std::map<std::string, Run> runs;  // by run_name; a later file's run replaces an earlier one's
    double fixed_range_m = std::nan(""), fixed_points = std::nan("");
    nlohmann::json context = nlohmann::json::object();
    for (int f = 2; f < argc; ++f) {
      const nlohmann::json results = read_results(argv[f]);
      if (context.empty()) context = results.value("context", nlohmann::json::object());
      std::map<std::string, Run> file_runs;
      for (const nlohmann::json& b : results["benchmarks"]) {
        if (b.value("error_occurred", false)) continue;
        Run parsed;
        const std::string run_name = b.value("run_name", b.value("name", std::string()));
        if (!parse_run_name(run_name, parsed)) continue;
        const bool aggregate = b.value("run_type", std::string("iteration")) == "aggregate";
        if (aggregate && b.value("aggregate_name", std::string()) != "median") continue;  // mean, stddev, cv
        Run& run = file_runs.emplace(run_name, parsed).first->second;
        const double s = seconds_of(b.at("real_time").get<double>(), b.at("time_unit").get<std::string>());
        if (aggregate) run.median = s;
        else run.seconds.push_back(s);
        // What each sweep holds fixed, for the panel titles.
        if (parsed.family == "BM_PointsPerScan" && b.contains("max_range_m"))
          fixed_range_m = b["max_range_m"].get<double>();
        if (parsed.family == "BM_MaxRange" && b.contains("points_per_scan"))
          fixed_points = b["points_per_scan"].get<double>();
      }
      for (auto& [name, run] : file_runs) runs[name] = run;
    }
    if (runs.empty()) throw std::runtime_error("no bench_scaling runs in the JSON given");

    bgkmap::eval::LinePanel by_points, by_range;
    char title[64];
    std::snprintf(title, sizeof title, "max range %g m", fixed_range_m);
    by_points.title = title;
    by_points.xlabel = "log10(points per scan)";
    std::snprintf(title, sizeof title, "%.0f points per scan", fixed_points);
    by_range.title = title;
    by_range.xlabel = "max range (m)";
    for (bgkmap::eval::LinePanel* p : {&by_points, &by_range}) {
      p->ylabel = "insert time per scan (s)";
      p->log_y = true;
    }
    std::map<std::tuple<std::string, int, std::string>, bgkmap::eval::LineSeries> series;  // (family, rank, method)
    for (const auto& [name, run] : runs) {  // run names sort by argument within a method only
      double s = run.median;
      if (std::isnan(s)) {
        if (run.seconds.empty()) continue;
        s = 0;
        for (double v : run.seconds) s += v;
        s /= static_cast<double>(run.seconds.size());
      }
      bgkmap::eval::LineSeries& line = series[{run.family, method_rank(run.method), run.method}];
      line.label = label_of(run.method, context);
      line.x.push_back(run.family == "BM_PointsPerScan" ? std::log10(run.x) : run.x);
      line.y.push_back(s);
    }
    for (auto& [key, line] : series) {
      // Order the points by x (run names sort as text: 1024 < 131072 < 16384).
      std::vector<size_t> order(line.x.size());
      for (size_t i = 0; i < order.size(); ++i) order[i] = i;
      std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return line.x[a] < line.x[b]; });
      bgkmap::eval::LineSeries sorted{line.label, {}, {}};
      for (size_t i : order) {
        sorted.x.push_back(line.x[i]);
        sorted.y.push_back(line.y[i]);
      }
      (std::get<0>(key) == "BM_PointsPerScan" ? by_points : by_range).series.push_back(sorted);
    }
    bgkmap::eval::write_line_panels_png(argv[1], {by_points, by_range}, 2,
                                        "Insert time per scan (median), synthetic lidar, 0.1 m cells, l = 0.2 m; machine: " +
                                            std::to_string(context.value("num_cpus", 0)) + " CPUs");
    std::printf("wrote %s (%zu lines)\n", argv[1], series.size());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "plot_scaling: %s\n", e.what());
    return 1;
  }
  return 0;
}
