// The Python module `bgkmap`: numpy arrays in and out of the library, no per-point Python code.
// Parameters are keywords with the CLI flags' names (dashes as underscores) and the library's
// defaults (params_io); bgkmap.build() runs the library's BuildSession; errors keep the one-line messages.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdint>
#include <cstdlib>
#include <fstream>
#include <filesystem>
#include <memory>
#include <mutex>
#include <new>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "bgkmap/build/build_session.hpp"
#include "bgkmap/core/memory_limit.hpp"
#include "bgkmap/methods/param_error.hpp"
#include "bgkmap/core/pose_covariance.hpp"
#include "bgkmap/core/params_io.hpp"
#include "bgkmap/eval/metrics.hpp"
#include "bgkmap/integrate/backend.hpp"
#include "bgkmap/io/atomic_file.hpp"
#include "bgkmap/io/errors.hpp"
#include "bgkmap/io/map_export.hpp"
#include "bgkmap/io/map_io.hpp"
#include "bgkmap/io/scan_source.hpp"
#include "bgkmap/map/map_queries.hpp"
#include "bgkmap/mapper.hpp"
#include "bgkmap/methods/method.hpp"
#include "bgkmap/methods/method_descriptor.hpp"
#include "bgkmap/viz/viewer.hpp"
#include "cli/build_options.hpp"
#include "cli/commands.hpp"
#include "cli/omp_wait_policy.hpp"
#include "cli/output_names.hpp"
#include "cli/progress.hpp"

namespace py = pybind11;

namespace bgkmap::python {

namespace {

using DoubleArray = py::array_t<double, py::array::c_style | py::array::forcecast>;

// ---- parameters -------------------------------------------------------------------------------

nlohmann::json to_json(const py::handle& value, const std::string& key) {
  if (py::isinstance<py::bool_>(value)) return value.cast<bool>();
  if (py::isinstance<py::int_>(value)) return value.cast<int64_t>();
  if (py::isinstance<py::float_>(value)) return value.cast<double>();
  if (py::isinstance<py::str>(value)) return value.cast<std::string>();
  // A numpy scalar (np.float32(0.2), np.int64(4)): its Python value.
  if (py::isinstance(value, py::module_::import("numpy").attr("generic"))) return to_json(value.attr("item")(), key);
  throw py::type_error("parameter '" + key + "' has the wrong type (" +
                       py::str(py::type::of(value).attr("__name__")).cast<std::string>() + ")");
}

py::object to_python(const nlohmann::json& json) { return py::module_::import("json").attr("loads")(json.dump()); }

const char* const kBackendKeys[] = {"backend", "threads", "device"};

bool is_backend_key(const std::string& key) {
  for (const char* k : kBackendKeys)
    if (key == k) return true;
  return false;
}

void set_backend_key(BackendOptions& backend, const std::string& key, const py::handle& value) {
  if (key == "threads") {
    if (!py::isinstance<py::int_>(value) || py::isinstance<py::bool_>(value))
      throw py::type_error("parameter 'threads' must be an int");
    backend.threads = value.cast<int>();
    if (backend.threads < 0) throw std::invalid_argument("--threads must be >= 0");
    return;
  }
  if (!py::isinstance<py::str>(value)) throw py::type_error("parameter '" + key + "' must be a str");
  (key == "backend" ? backend.backend : backend.device_filter) = value.cast<std::string>();
}

// Keywords a Mapper takes beside the defaults' keys: `frame` (as --frame; apply_viewpoint is its
// alias) and the planar keys, which only planar maps' parameters carry.
const char* const kExtraKeys[] = {"frame", "planar", "plane_z"};

std::string accepted_keywords() {
  std::string out;
  const nlohmann::json defaults = params_to_json(BuildParams{});
  for (const auto& item : defaults.items()) out += (out.empty() ? "" : ", ") + item.key();
  for (const char* k : kExtraKeys) out += std::string(", ") + k;
  for (const char* k : kBackendKeys) out += std::string(", ") + k;
  return out;
}

// Keywords -> the build's settings, on top of `base` (the defaults, or a stored map's parameters).
struct Settings {
  BuildParams params;
  BackendOptions backend;
};

// frame='world' or 'sensor', as --frame takes it.
PointFrame point_frame(const py::handle& value) {
  if (!py::isinstance<py::str>(value)) throw py::type_error("frame must be a str, 'world' or 'sensor'");
  const std::string name = value.cast<std::string>();
  if (name != "world" && name != "sensor") throw std::invalid_argument("frame must be 'world' or 'sensor', not '" + name + "'");
  return name == "sensor" ? PointFrame::kSensor : PointFrame::kWorld;
}

Settings settings_from(const py::kwargs& kwargs, const BuildParams& base = BuildParams{}) {
  Settings s;
  nlohmann::json params = params_to_json(base);
  for (const auto& item : kwargs) {
    const std::string key = item.first.cast<std::string>();
    if (is_backend_key(key)) {
      set_backend_key(s.backend, key, item.second);
    } else if (key == "frame") {
      if (kwargs.contains("apply_viewpoint")) throw py::type_error("give frame or apply_viewpoint, not both");
      params["apply_viewpoint"] = point_frame(item.second) == PointFrame::kSensor;
    } else if (params.contains(key) || key == "planar" || key == "plane_z") {
      params[key] = to_json(item.second, key);
    } else {
      throw py::type_error("unknown parameter '" + key + "' (accepted: " + accepted_keywords() + ")");
    }
  }
  if (params.contains("plane_z") && !params.value("planar", false))
    throw std::invalid_argument("plane_z is the height of a planar map: give planar=True with it");
  s.params = params_from_json(params);
  // As `bgkmap build --2d`: the plane is the centre plane of the layer holding plane_z.
  if (s.params.preprocess.planar && std::isfinite(s.params.preprocess.plane_z_m) && s.params.grid.resolution_m > 0)
    s.params.set_planar(s.params.preprocess.plane_z_m);
  s.params.validate();
  return s;
}

// `bgkmap build`'s description of a flag (its units), from the command itself.
std::string flag_help(const CLI::App& build, const std::string& flag) {
  const CLI::Option* option = build.get_option_no_throw(flag);
  return option ? option->get_description() : std::string();
}

// One line a keyword: its default as Python writes it, then what `bgkmap build --help` says of the flag.
std::string keyword_doc() {
  CLI::App app{"bgkmap"};
  cli::add_build_command(app);
  const CLI::App& build = *app.get_subcommand("build");
  const auto line = [&](const std::string& key, const py::object& value, const std::string& flag) {
    return "    " + key + "=" + py::repr(value).cast<std::string>() + ": " + flag_help(build, flag) + "\n";
  };
  std::string doc;
  const nlohmann::json defaults = params_to_json(BuildParams{});
  for (const auto& item : defaults.items()) {
    std::string flag = "--" + item.key();
    for (char& c : flag)
      if (c == '_') c = '-';
    if (item.key() == "apply_viewpoint")
      doc += line("frame", py::str("world"), "--frame") +
             "    apply_viewpoint=False: True is frame='sensor' (the name in params, .bgk files and reports)\n";
    else
      doc += line(item.key(), to_python(item.value()), flag);
  }
  const PreprocessParams preprocess;
  doc += line("planar", py::bool_(preprocess.planar), "--2d");
  doc += line("plane_z", py::float_(preprocess.plane_z_m), "--plane-z");
  const BackendOptions backend;
  doc += line("backend", py::str(backend.backend), "--backend");
  doc += line("threads", py::int_(backend.threads), "--threads");
  doc += line("device", py::str(backend.device_filter), "--device");
  return doc;
}

// ---- arrays -----------------------------------------------------------------------------------

std::string shape_of(const py::array& a) {
  std::string s = "(";
  for (py::ssize_t d = 0; d < a.ndim(); ++d) s += (d ? ", " : "") + std::to_string(a.shape(d));
  return s + (a.ndim() == 1 ? ",)" : ")");
}

std::string dtype_of(const py::array& a) { return py::str(a.dtype()).cast<std::string>(); }

// `a` as a C-ordered array of T (a copy where it is not one already). pybind11's ensure() returns a
// null array when the copy cannot be made (a broadcast view of 3e8 rows): MemoryError, not a crash.
template <typename Array>
Array converted(const py::array& a) {
  Array out = Array::ensure(a);
  if (!out) throw std::bad_alloc();
  return out;
}

// Integers and floats convert to float64 exactly enough for coordinates; bool, complex, strings
// and objects have no coordinate to give.
bool holds_real_numbers(const py::array& a) {
  const char kind = a.dtype().kind();
  return kind == 'f' || kind == 'i' || kind == 'u';
}

// `object` (an array, or a list or tuple numpy reads as one) as float64, refused naming the dtype
// numpy gave it when that holds no real numbers.
py::array real_array(const py::object& object, const std::string& name, const char* shape_text) {
  const py::array a = py::array::ensure(object);
  if (!a) throw py::type_error(name + " must be an array-like of numbers of shape " + shape_text);
  if (!holds_real_numbers(a))
    throw py::type_error(name + " must hold integers or floats, got " + dtype_of(a));
  return a;
}

// Points (N, 3) as doubles: any array-like of real numbers, of any memory layout.
DoubleArray points_array(const py::object& object, const char* name) {
  const py::array a = real_array(object, name, "(N, 3)");
  if (a.ndim() != 2 || a.shape(1) != 3)
    throw py::value_error(std::string(name) + " must have shape (N, 3), got " + shape_of(a));
  return converted<DoubleArray>(a);
}

DoubleArray fixed_array(const py::object& object, const char* name, std::initializer_list<py::ssize_t> shape,
                        const char* shape_text) {
  const py::array a = real_array(object, name, shape_text);
  bool ok = a.ndim() == static_cast<py::ssize_t>(shape.size());
  size_t d = 0;
  for (py::ssize_t n : shape) ok = ok && a.shape(d++) == n;
  if (!ok) throw py::value_error(std::string(name) + " must have shape " + shape_text + ", got " + shape_of(a));
  const DoubleArray out = converted<DoubleArray>(a);
  for (py::ssize_t i = 0; i < out.size(); ++i)
    if (!std::isfinite(out.data()[i])) throw py::value_error(std::string(name) + " holds NaN or Inf");
  return out;
}

// Query points must be finite and within the keys' reach: a NaN or a point at 1e30 m has no
// cell (`bgkmap query` refuses such a line too).
void check_query_points(const DoubleArray& points, const char* name) {
  const double* p = points.data();
  for (py::ssize_t i = 0; i < points.shape(0); ++i)
    if (!std::isfinite(p[3 * i]) || !std::isfinite(p[3 * i + 1]) || !std::isfinite(p[3 * i + 2]))
      throw py::value_error(std::string(name) + "[" + std::to_string(i) + "] is not finite");
    else if (!within_key_range(p[3 * i], p[3 * i + 1], p[3 * i + 2]))
      throw py::value_error(std::string(name) + "[" + std::to_string(i) +
                            "] lies beyond the map's key range (|x|, |y|, |z| at most 1e6 m)");
}

template <typename T>
py::array_t<T> vector_array(std::vector<T>&& values) {
  auto* heap = new std::vector<T>(std::move(values));
  py::capsule owner(heap, [](void* p) { delete static_cast<std::vector<T>*>(p); });
  return py::array_t<T>(static_cast<py::ssize_t>(heap->size()), heap->data(), owner);
}

py::array_t<double> rows_of_three(std::vector<double>&& values) {
  auto* heap = new std::vector<double>(std::move(values));
  py::capsule owner(heap, [](void* p) { delete static_cast<std::vector<double>*>(p); });
  const py::ssize_t rows = static_cast<py::ssize_t>(heap->size() / 3);
  return py::array_t<double>({rows, py::ssize_t{3}}, heap->data(), owner);
}

// ---- scans ------------------------------------------------------------------------------------

// progress(done, total) as Python sees it: total None when not known (0).
void call_progress(const py::object& progress, uint64_t done, uint64_t total) {
  progress(done, total ? py::object(py::int_(total)) : py::object(py::none()));
}

py::dict scan_dict(Scan&& scan) {
  std::vector<float> xyz(scan.points.size() * 3);
  for (size_t i = 0; i < scan.points.size(); ++i) {
    xyz[3 * i] = scan.points[i].x;
    xyz[3 * i + 1] = scan.points[i].y;
    xyz[3 * i + 2] = scan.points[i].z;
  }
  auto* heap = new std::vector<float>(std::move(xyz));
  py::capsule owner(heap, [](void* p) { delete static_cast<std::vector<float>*>(p); });
  py::dict d;
  d["points"] = py::array_t<float>({static_cast<py::ssize_t>(scan.points.size()), py::ssize_t{3}}, heap->data(), owner);
  d["origin"] = vector_array(std::vector<double>{scan.pose.position.x, scan.pose.position.y, scan.pose.position.z});
  d["orientation"] = vector_array(std::vector<double>{scan.pose.qw, scan.pose.qx, scan.pose.qy, scan.pose.qz});
  d["in_world_frame"] = scan.points_in_world_frame;
  d["source"] = scan.source;
  return d;
}

// A str, bytes or os.PathLike (pathlib.Path) as a path; anything else is os.fsdecode's TypeError.
std::string path_text(const py::handle& path) {
  return py::module_::import("os").attr("fsdecode")(path).cast<std::string>();
}

// One path, or a list or tuple of them.
std::vector<std::filesystem::path> paths_of(const py::object& paths) {
  std::vector<std::filesystem::path> out;
  if (py::isinstance<py::str>(paths) || py::isinstance<py::bytes>(paths) || py::hasattr(paths, "__fspath__")) {
    out.emplace_back(path_text(paths));
    return out;
  }
  for (const py::handle& p : paths) out.emplace_back(path_text(p));
  return out;
}

// --poses / --origin: where inputs without a pose of their own (PLY, XYZ, PCD without a VIEWPOINT)
// were taken from; --frame: "world", "sensor" or None.
ScanSourceOptions source_options(const py::object& poses, const py::object& origin, const py::object& frame) {
  if (!poses.is_none() && !origin.is_none()) throw std::invalid_argument("give --poses or --origin, not both");
  ScanSourceOptions options;
  if (!frame.is_none()) options.frame = point_frame(frame);
  if (!poses.is_none()) options.poses = path_text(poses);
  if (!origin.is_none()) {
    const DoubleArray o = fixed_array(origin, "origin", {3}, "(3,)");
    options.origin = Vec3f{float(o.data()[0]), float(o.data()[1]), float(o.data()[2])};
  }
  return options;
}

std::vector<py::dict> read_scans(const py::object& paths, const py::object& poses, const py::object& origin,
                                 const py::object& frame) {
  ScanSource source(paths_of(paths), source_options(poses, origin, frame));
  std::vector<py::dict> out;
  for (;;) {
    Scan scan;
    bool more;
    {
      py::gil_scoped_release release;
      more = source.next(scan);
    }
    if (!more) break;
    out.push_back(scan_dict(std::move(scan)));
  }
  return out;
}

// ---- map queries ------------------------------------------------------------------------------

// A box from its corners, each (3,); both None: no box.
std::optional<CellBox> box_of(const py::object& lo, const py::object& hi) {
  if (lo.is_none() && hi.is_none()) return std::nullopt;
  if (lo.is_none() || hi.is_none()) throw py::type_error("give both corners of the box, lo and hi, or neither");
  const DoubleArray a = fixed_array(lo, "lo", {3}, "(3,)"), b = fixed_array(hi, "hi", {3}, "(3,)");
  const CellBox box{{a.data()[0], a.data()[1], a.data()[2]}, {b.data()[0], b.data()[1], b.data()[2]}};
  check_cell_box(box);
  return box;
}

// ---- the mapper -------------------------------------------------------------------------------

class PyMapper {
 public:
  PyMapper(BgkMap map, const BackendOptions& backend, std::vector<HeldInput> held = {}, std::string method = "bgkl")
      : mapper_(std::make_unique<Mapper>(std::move(map), make_integrator(cli::with_environment(backend)))),
        held_(std::move(held)),
        method_(std::move(method)) {}

  static std::unique_ptr<PyMapper> from_keywords(const py::kwargs& kwargs) {
    const Settings s = settings_from(kwargs);
    return std::make_unique<PyMapper>(BgkMap(s.params), s.backend);
  }

  void insert(const py::object& points_object, const py::object& origin_object, const py::object& pose_object) {
    check_bgkl();
    if (origin_object.is_none() == pose_object.is_none())
      throw py::type_error("insert() takes exactly one of origin (3,) or pose (4, 4)");
    const DoubleArray points = points_array(points_object, "points");
    Scan scan;
    scan.points_in_world_frame = true;
    scan.source = "<array>";
    const double* p = points.data();
    const size_t n = static_cast<size_t>(points.shape(0));
    scan.points.resize(n);
    if (!origin_object.is_none()) {
      const DoubleArray origin = fixed_array(origin_object, "origin", {3}, "(3,)");
      scan.pose.position = {float(origin.data()[0]), float(origin.data()[1]), float(origin.data()[2])};
      for (size_t i = 0; i < n; ++i) scan.points[i] = {float(p[3 * i]), float(p[3 * i + 1]), float(p[3 * i + 2])};
    } else {
      const DoubleArray pose = fixed_array(pose_object, "pose", {4, 4}, "(4, 4)");
      const double* m = pose.data();
      check_rigid(m);
      scan.pose.position = {float(m[3]), float(m[7]), float(m[11])};
      for (size_t i = 0; i < n; ++i) {
        const double x = p[3 * i], y = p[3 * i + 1], z = p[3 * i + 2];
        scan.points[i] = {float(m[0] * x + m[1] * y + m[2] * z + m[3]), float(m[4] * x + m[5] * y + m[6] * z + m[7]),
                          float(m[8] * x + m[9] * y + m[10] * z + m[11])};
      }
    }
    py::gil_scoped_release release;
    std::lock_guard<std::mutex> lock(mutex_);
    mapper_->insert(scan);
  }

  // As `bgkmap build --resume`: the scans of these files the map already holds (same contents) are
  // passed over, and the ones inserted are recorded for save(). `progress(done, total)` after each
  // scan, without the map's lock, so that it may query the map.
  uint64_t insert_file(const py::object& paths, const py::object& poses, const py::object& origin,
                       const py::object& frame, const py::object& progress) {
    check_bgkl();
    if (!progress.is_none() && !PyCallable_Check(progress.ptr()))
      throw py::type_error("progress must be a callable progress(done, total), or None");
    ScanSourceOptions options = source_options(poses, origin, frame);
    const PreprocessParams& preprocess = mapper_->params().preprocess;
    const PointFrame mapped = preprocess.apply_viewpoint ? PointFrame::kSensor : PointFrame::kWorld;
    if (options.frame && *options.frame != mapped)
      throw std::invalid_argument(std::string("frame='") + (*options.frame == PointFrame::kSensor ? "sensor" : "world") +
                                  "' but the Mapper's frame is '" + (preprocess.apply_viewpoint ? "sensor" : "world") +
                                  "' (apply_viewpoint=" + (preprocess.apply_viewpoint ? "True" : "False") + ")");
    if (preprocess.apply_viewpoint) options.frame = PointFrame::kSensor;
    options.kitti_frame = preprocess.kitti_frame;
    ScanSource source(paths_of(paths), options);
    py::gil_scoped_release release;
    std::unique_lock<std::mutex> lock(mutex_);
    source.skip_held(held_.match(source.files()));
    uint64_t scans = 0;
    ScanProgress told{~uint64_t{0}};
    const auto tell = [&] {
      const ScanProgress now = source.progress();
      if (progress.is_none() || (now.done == told.done && now.total == told.total)) return;
      told = now;
      report_progress(progress, now, lock);
    };
    tell();
    for (Scan scan; source.next(scan); ++scans) {
      mapper_->insert(scan);
      held_.add(source.files(), source.last_file(), source.last_scan());
      tell();
    }
    tell();  // held scans passed over at the end
    return scans;
  }

  py::tuple query(const py::object& points_object) {
    const DoubleArray points = points_array(points_object, "points");
    check_query_points(points, "points");
    const size_t n = static_cast<size_t>(points.shape(0));
    std::vector<double> alpha(n), beta(n);
    {
      py::gil_scoped_release release;
      std::lock_guard<std::mutex> lock(mutex_);
      const BgkMap& map = mapper_->map();
      const double* p = points.data();
      for (size_t i = 0; i < n; ++i) {
        const CellPosterior c = map.query(p[3 * i], p[3 * i + 1], p[3 * i + 2]);
        alpha[i] = c.alpha;
        beta[i] = c.beta;
      }
    }
    return py::make_tuple(vector_array(std::move(alpha)), vector_array(std::move(beta)));
  }

  // f(posterior) at each point, as one array.
  template <typename T, typename F>
  py::array_t<T> per_point(const py::object& points_object, F f) {
    const DoubleArray points = points_array(points_object, "points");
    check_query_points(points, "points");
    const size_t n = static_cast<size_t>(points.shape(0));
    std::vector<T> out(n);
    {
      py::gil_scoped_release release;
      std::lock_guard<std::mutex> lock(mutex_);
      const BgkMap& map = mapper_->map();
      const double* p = points.data();
      for (size_t i = 0; i < n; ++i) out[i] = f(map, map.query(p[3 * i], p[3 * i + 1], p[3 * i + 2]));
    }
    return vector_array(std::move(out));
  }

  py::tuple cells() {
    std::vector<double> centres, alpha, beta;
    {
      py::gil_scoped_release release;
      std::lock_guard<std::mutex> lock(mutex_);
      const BgkMap& map = mapper_->map();
      const size_t n = map.cells_with_evidence();
      centres.reserve(3 * n);
      alpha.reserve(n);
      beta.reserve(n);
      map.for_each_cell_with_evidence([&](const CellIndex& cell, const CellPosterior& p) {
        const Vec3d c = map.grid().cell_center_d(cell);
        centres.insert(centres.end(), {c.x, c.y, c.z});
        alpha.push_back(p.alpha);
        beta.push_back(p.beta);
      });
    }
    return py::make_tuple(rows_of_three(std::move(centres)), vector_array(std::move(alpha)),
                          vector_array(std::move(beta)));
  }

  // Ray casts (docs/QUERIES.md): a dict of arrays, one row per ray.
  py::dict cast_rays(const py::object& origins_object, const py::object& directions_object,
                     const py::object& max_range_object, const std::string& unknown) {
    const UnknownPolicy policy = unknown_policy_from_string(unknown);
    const DoubleArray origins = points_array(origins_object, "origins");
    const DoubleArray directions = points_array(directions_object, "directions");
    const size_t n = static_cast<size_t>(origins.shape(0));
    if (static_cast<size_t>(directions.shape(0)) != n)
      throw py::value_error("directions must have as many rows as origins (" + std::to_string(n) + "), got " +
                            shape_of(directions));
    const DoubleArray ranges = DoubleArray::ensure(py::array::ensure(max_range_object));
    if (!ranges || !(ranges.ndim() == 0 || (ranges.ndim() == 1 && static_cast<size_t>(ranges.shape(0)) == n)))
      throw py::value_error("max_range must be a number or an array of shape (" + std::to_string(n) + ",)");
    py::array_t<bool> hit(static_cast<py::ssize_t>(n));
    std::vector<double> centres(3 * n), distance(n);
    std::vector<uint8_t> state(n), stop(n);
    bool* hit_data = hit.mutable_data();
    {
      py::gil_scoped_release release;
      std::lock_guard<std::mutex> lock(mutex_);
      const RayCaster caster(mapper_->map());
      const double *o = origins.data(), *d = directions.data();
      for (size_t i = 0; i < n; ++i) {
        const double range = ranges.data()[ranges.ndim() == 0 ? 0 : i];
        RayCast ray;
        try {
          ray = caster.cast({o[3 * i], o[3 * i + 1], o[3 * i + 2]}, {d[3 * i], d[3 * i + 1], d[3 * i + 2]}, range, policy);
        } catch (const std::invalid_argument& e) {
          throw std::invalid_argument("ray " + std::to_string(i) + ": " + e.what());
        }
        hit_data[i] = ray.hit();
        centres[3 * i] = ray.center.x, centres[3 * i + 1] = ray.center.y, centres[3 * i + 2] = ray.center.z;
        distance[i] = ray.distance;
        state[i] = static_cast<uint8_t>(ray.state);
        stop[i] = static_cast<uint8_t>(ray.stop);
      }
    }
    py::dict out;
    out["hit"] = hit;
    out["centres"] = rows_of_three(std::move(centres));
    out["distance"] = vector_array(std::move(distance));
    out["state"] = vector_array(std::move(state));
    out["stop"] = vector_array(std::move(stop));
    return out;
  }

  // The selected cells of a box (or the whole map) as a dict of arrays.
  py::dict box_cells(const std::optional<CellBox>& box, CellSelection selection) {
    std::vector<double> centres, alpha, beta;
    std::vector<uint8_t> state;
    {
      py::gil_scoped_release release;
      std::lock_guard<std::mutex> lock(mutex_);
      const BgkMap& map = mapper_->map();
      if (box && selection == CellSelection::kAll)
        require_memory(cells_centred_in(map, *box) * 64, "the box's cells", "give a smaller box");
      for_each_cell_in_box(map, box ? &*box : nullptr, selection, [&](const MapCell& c) {
        centres.insert(centres.end(), {c.center.x, c.center.y, c.center.z});
        alpha.push_back(c.posterior.alpha);
        beta.push_back(c.posterior.beta);
        state.push_back(static_cast<uint8_t>(c.state));
      });
    }
    py::dict out;
    out["centres"] = rows_of_three(std::move(centres));
    out["alpha"] = vector_array(std::move(alpha));
    out["beta"] = vector_array(std::move(beta));
    out["state"] = vector_array(std::move(state));
    return out;
  }

  void write(const py::object& path_object, const std::string& ot_values) {
    const std::string path = path_text(path_object);
    const TreeValues values = tree_values_from_string(ot_values);
    py::gil_scoped_release release;
    std::lock_guard<std::mutex> lock(mutex_);
    if (map_format_from_path(path) == MapFormat::kNative) write_native_map(path, mapper_->lazy_map(), held_.records(), method_);
    else write_map(path, mapper_->map(), method_, values);
  }

  // A .pgm of a 3-D map over the height band [z_min, z_max] (both or neither), as `bgkmap export`.
  void export_band(const py::object& path_object, const std::string& ot_values, std::optional<double> z_min,
                   std::optional<double> z_max) {
    if (z_min.has_value() != z_max.has_value()) throw std::invalid_argument("z_min and z_max go together");
    if (!z_min) return write(path_object, ot_values);
    const std::string path = path_text(path_object);
    const HeightBand band = height_band_between(*z_min, *z_max);
    if (map_format_from_path(path) != MapFormat::kRosMap)
      throw std::invalid_argument(path + ": z_min/z_max select the heights of a .pgm only");
    py::gil_scoped_release release;
    std::lock_guard<std::mutex> lock(mutex_);
    write_map_export(path, export_cells(mapper_->map()), band);
  }

  py::object params() const { return to_python(params_to_json(mapper_->params())); }

  py::object counts() {
    std::lock_guard<std::mutex> lock(mutex_);
    mapper_->finish();
    // The names of `bgkmap build`'s report.
    static const std::pair<const char*, uint64_t PreprocessCounts::*> kPreprocess[] = {
        {"points_read", &PreprocessCounts::points_read},
        {"dropped_nonfinite", &PreprocessCounts::dropped_nonfinite},
        {"dropped_out_of_key_range", &PreprocessCounts::dropped_out_of_key_range},
        {"dropped_beyond_reach", &PreprocessCounts::dropped_beyond_reach},
        {"removed_by_downsampling", &PreprocessCounts::removed_by_downsampling},
        {"beyond_max_range", &PreprocessCounts::beyond_max_range},
        {"no_returns", &PreprocessCounts::no_returns},
        {"no_returns_dropped", &PreprocessCounts::no_returns_dropped},
        {"hits", &PreprocessCounts::hits},
        {"beams", &PreprocessCounts::beams},
        {"beams_shorter_than_margin", &PreprocessCounts::beams_shorter_than_margin}};
    nlohmann::json counts = {{"scans", mapper_->counts().scans},
                             {"blocks_touched", mapper_->map().block_count()},
                             {"cells_with_evidence", mapper_->map().cells_with_evidence()}};
    for (const auto& [name, field] : kPreprocess) counts[name] = mapper_->counts().preprocess.*field;
    return to_python(counts);
  }

  py::object backend() const {
    const BackendInfo b = mapper_->backend();
    return to_python({{"name", b.name}, {"device", b.device}, {"threads", b.threads}, {"note", b.note}, {"reason", b.reason}});
  }

  std::string repr() {
    std::lock_guard<std::mutex> lock(mutex_);
    const BgkMap& map = mapper_->map();
    const BuildParams& p = map.params();
    std::string shape = "3-D";
    if (p.preprocess.planar) shape = "2-D at z=" + py::repr(py::float_(p.preprocess.plane_z_m)).cast<std::string>() + " m";
    return "<bgkmap.Mapper " + method_ + ", " + shape + ", resolution " +
           py::repr(py::float_(p.grid.resolution_m)).cast<std::string>() + " m, " +
           std::to_string(map.cells_with_evidence()) + " cells with evidence>";
  }

 private:
  // Calls progress(done, total) with the GIL and without `lock` (the map's), which it takes back.
  static void report_progress(const py::object& progress, const ScanProgress& p, std::unique_lock<std::mutex>& lock) {
    lock.unlock();
    {
      py::gil_scoped_acquire gil;
      call_progress(progress, p.done, p.total);
    }
    lock.lock();
  }

  static void check_rigid(const double* m) {
    if (m[12] != 0 || m[13] != 0 || m[14] != 0 || m[15] != 1)
      throw py::value_error("pose must be a rigid transform: its last row must be [0, 0, 0, 1]");
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) {
        const double dot = m[4 * 0 + a] * m[4 * 0 + b] + m[4 * 1 + a] * m[4 * 1 + b] + m[4 * 2 + a] * m[4 * 2 + b];
        if (std::abs(dot - (a == b ? 1.0 : 0.0)) > 1e-5)
          throw py::value_error("pose must be a rigid transform: its 3x3 rotation is not orthonormal");
      }
    const double det = m[0] * (m[5] * m[10] - m[6] * m[9]) - m[1] * (m[4] * m[10] - m[6] * m[8]) +
                       m[2] * (m[4] * m[9] - m[5] * m[8]);
    if (det < 0) throw py::value_error("pose must be a rigid transform: its 3x3 part is a reflection (determinant -1)");
  }

  // A loaded map of bgk or counting is read and written, not continued: its alpha and beta mean
  // other evidence than a BGK-L update would add.
  void check_bgkl() const {
    if (method_ != "bgkl")
      throw py::value_error("this map was built by --method " + method_ + ": a Mapper continues BGK-L maps only");
  }

  std::unique_ptr<Mapper> mapper_;
  HeldInputs held_;   // the scans of files the map holds (insert_file; a loaded map's record)
  std::string method_;  // the method that built the map (a loaded .bgk's)
  std::mutex mutex_;  // inserts and queries run without the GIL
};

std::unique_ptr<PyMapper> load(const py::object& path_object, const py::kwargs& kwargs) {
  const std::string path = path_text(path_object);
  NativeMapFile file = [&] {
    py::gil_scoped_release release;
    return read_native_map_file(path, StoredTime::kAsStored);  // a Mapper continues it
  }();
  BackendOptions backend;
  for (const auto& item : kwargs) {
    const std::string key = item.first.cast<std::string>();
    if (!is_backend_key(key)) throw py::type_error("load() takes backend, threads and device, not '" + key + "'");
    set_backend_key(backend, key, item.second);
  }
  return std::make_unique<PyMapper>(std::move(file.map), backend, std::move(file.held), std::move(file.method));
}

// ---- build ------------------------------------------------------------------------------------

// bgkmap.METHOD_PARAMS: each method's own parameters, keyword -> default, from its descriptor.
py::dict method_params_dict() {
  py::dict out;
  for (const MethodDescriptor* method : method_descriptors()) {
    py::dict defaults;
    for (const ParamSpec* spec : method->params) {
      const py::str keyword(spec->keyword());
      if (spec->kind == ParamKind::kChoice) defaults[keyword] = spec->default_choice;
      else if (spec->kind == ParamKind::kWholeNumber) defaults[keyword] = static_cast<long>(spec->default_number);
      else defaults[keyword] = spec->default_number;
    }
    out[py::str(method->name)] = defaults;
  }
  return out;
}

// The keywords as `bgkmap build` flags: max_range=8 -> --max-range 8, True -> the bare flag,
// False or None -> left out, a list -> the flag once per item.
void add_flags(std::vector<std::string>& args, const py::kwargs& kwargs) {
  for (const auto& item : kwargs) {
    std::string flag = "--" + item.first.cast<std::string>();
    for (char& c : flag)
      if (c == '_') c = '-';
    const py::handle value = item.second;
    if (value.is_none() || (py::isinstance<py::bool_>(value) && !value.cast<bool>())) continue;
    if (py::isinstance<py::bool_>(value)) {
      args.push_back(flag);
    } else if (py::isinstance<py::list>(value) || py::isinstance<py::tuple>(value)) {
      for (const py::handle& v : value) args.insert(args.end(), {flag, py::str(v).cast<std::string>()});
    } else {
      args.insert(args.end(), {flag, py::str(value).cast<std::string>()});
    }
  }
}

// A folder of its own, removed afterwards.
class TemporaryFolder {
 public:
  TemporaryFolder() {
    std::string pattern = (std::filesystem::temp_directory_path() / "bgkmap-python-XXXXXX").string();
    if (!::mkdtemp(pattern.data())) throw std::runtime_error("cannot create a temporary folder in " + pattern);
    path_ = pattern;
  }
  ~TemporaryFolder() {
    std::error_code ignored;
    std::filesystem::remove_all(path_, ignored);
  }
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

// Runs one subcommand of the CLI (`args` from "bgkmap" on) in this process, without the GIL; a usage
// error is a ValueError.
void run_command(std::vector<std::string>& args, void (*add_command)(CLI::App&)) {
  py::gil_scoped_release release;
  CLI::App app{"bgkmap"};
  app.require_subcommand(1);
  add_command(app);
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  try {
    app.parse(static_cast<int>(argv.size()), argv.data());
  } catch (const CLI::ParseError& e) {
    throw std::invalid_argument(e.what());
  }
}

// build()'s keywords by where they go: the map's parameters (over the defaults, a config's or a
// resumed map's), the back end (over a config's), and the rest straight into the request.
struct BuildKeywords {
  nlohmann::json params = nlohmann::json::object();
  std::vector<std::pair<std::string, py::object>> backend;
  std::optional<PointFrame> frame;
};

// A keyword's value as the text its flag would be given (a path, a name, "4G").
std::string keyword_text(const py::handle& value) {
  if (py::isinstance<py::str>(value) || py::hasattr(value, "__fspath__")) return path_text(value);
  return py::str(value).cast<std::string>();
}

// `base` with the keywords' parameters, as `bgkmap build` applies its flags over the defaults or a config.
BuildParams params_over(const BuildParams& base, const nlohmann::json& given) {
  nlohmann::json json = params_to_json(base);
  json.update(given);
  if (json.contains("plane_z") && !json.value("planar", false))
    throw std::invalid_argument("plane_z is the height of a planar map: give planar=True with it");
  BuildParams params;
  try {
    params = params_from_json(json);
  } catch (const nlohmann::json::exception&) {  // a str where a number goes, ...
    throw std::invalid_argument("a parameter keyword has a value of the wrong type (" + given.dump() + ")");
  }
  if (params.preprocess.planar && std::isfinite(params.preprocess.plane_z_m) && params.grid.resolution_m > 0)
    params.set_planar(params.preprocess.plane_z_m);  // as --2d: the centre plane of the layer holding plane_z
  params.validate();
  return params;
}

// A keyword of the map's parameters into `given`; false for any other.
bool add_param_keyword(nlohmann::json& given, const std::string& key, const py::handle& value) {
  static const nlohmann::json defaults = params_to_json(BuildParams{});
  if (key == "pose_sigma") {  // "XY,YAW[,Z,ROLLPITCH]", as --pose-sigma
    const PoseSigma ps = parse_pose_sigma(keyword_text(value), "--pose-sigma");
    given["pose_sigma"] = {ps.xy_m, ps.yaw_rad, ps.z_m, ps.roll_pitch_rad};
  } else if (key == "pose_fusion") {
    given[key] = to_string(pose_fusion_from_string(keyword_text(value)));
  } else if (key == "kitti_frame") {
    given[key] = to_string(kitti_frame_from_string(keyword_text(value)));
  } else if (key == "planar" || key == "2d") {
    given["planar"] = to_json(value, key);
  } else if (defaults.contains(key) || key == "plane_z") {
    given[key] = to_json(value, key);
  } else {
    return false;
  }
  return true;
}

// A keyword of the scans' source, resuming, outputs or memory into `req`; false for any other.
bool add_request_keyword(BuildRequest& req, const std::string& key, const py::handle& value) {
  if (key == "poses") req.source.poses = keyword_text(value);
  else if (key == "pose_covariance") req.source.pose_covariance = keyword_text(value);
  else if (key == "tf_frame") req.source.tf_frame = keyword_text(value);
  else if (key == "topic") {
    if (py::isinstance<py::str>(value)) req.source.topics = {value.cast<std::string>()};
    else req.source.topics = value.cast<std::vector<std::string>>();
  } else if (key == "origin") {
    const std::vector<double> xyz = value.cast<std::vector<double>>();
    if (xyz.size() != 3) throw std::invalid_argument("--origin: expects X,Y,Z (3 values)");
    req.source.origin = Vec3f{static_cast<float>(xyz[0]), static_cast<float>(xyz[1]), static_cast<float>(xyz[2])};
  } else if (key == "resume") req.resume.resume = keyword_text(value);
  else if (key == "checkpoint") {
    std::string name = keyword_text(value);
    if (const std::string problem = cli::output_extension({".bgk"}, "a checkpoint is a native .bgk map")(name);
        !problem.empty())
      throw std::invalid_argument("--checkpoint: " + problem);
    req.resume.checkpoint = name;
  }
  else if (key == "checkpoint_every") {
    if (!py::isinstance<py::int_>(value) || value.cast<int64_t>() < 0)
      throw std::invalid_argument("--checkpoint-every: '" + py::str(value).cast<std::string>() +
                                  "' is not a count of scans (0 = none)");
    req.resume.every = value.cast<uint64_t>();
  } else if (key == "skip_bad_inputs") req.skip_bad_inputs = value.cast<bool>();
  else if (key == "ot_values") req.ot_values = tree_values_from_string(keyword_text(value));
  else if (key == "report") req.report = keyword_text(value);
  else if (key == "max_memory") set_memory_limit_bytes(parse_byte_size(keyword_text(value)));
  else if (key == "shards") throw std::invalid_argument("--shards is for a build under mpirun");
  else return key == "quiet";  // the build prints nothing here anyway
  return true;
}

// The one place build() touches the method parameters: a keyword of them, by its report key.
bool add_method_keyword(MethodParams& params, const std::string& key, const py::handle& value) {
  return cli::set_method_param(params, key, to_json(value, key));
}

// Sorts the keywords into `req` and `kw`; an unknown one is refused as the command refuses its flag.
void sort_keywords(const py::kwargs& kwargs, BuildRequest& req, BuildKeywords& kw) {
  for (const auto& item : kwargs) {
    const std::string key = item.first.cast<std::string>();
    const py::handle value = item.second;
    // As the flags: None or False leaves the flag out.
    if (value.is_none() || (py::isinstance<py::bool_>(value) && !value.cast<bool>()) || key == "config") continue;
    if (is_backend_key(key)) kw.backend.emplace_back(key, py::reinterpret_borrow<py::object>(value));
    else if (key == "frame" || key == "apply_viewpoint") {
      if (key == "frame" && kwargs.contains("apply_viewpoint")) throw py::type_error("give frame or apply_viewpoint, not both");
      const bool sensor = key == "frame" ? point_frame(value) == PointFrame::kSensor : value.cast<bool>();
      kw.params["apply_viewpoint"] = sensor;
      kw.frame = sensor ? PointFrame::kSensor : PointFrame::kWorld;
    } else if (!add_param_keyword(kw.params, key, value) && !add_request_keyword(req, key, value) &&
               !add_method_keyword(req.method_params, key, value)) {
      throw py::type_error("build() got an unknown keyword '" + key +
                           "' (its keywords are bgkmap build's flags with underscores, and bgkmap.METHOD_PARAMS)");
    }
  }
}

// The request `bgkmap build` would make of these keywords as flags: defaults, then the config,
// then the keywords.
BuildRequest build_request(const std::string& method, const py::kwargs& kwargs) {
  const std::vector<std::string>& names = method_names();
  if (std::find(names.begin(), names.end(), method) == names.end()) {
    std::string list;
    for (const std::string& n : names) list += (list.empty() ? "" : ",") + n;
    throw std::invalid_argument("--method: " + method + " not in {" + list + "}");
  }
  BuildRequest req;
  req.method = method;
  cli::BuildConfig config;
  const std::string config_file = kwargs.contains("config") && !kwargs["config"].is_none()
                                      ? keyword_text(kwargs["config"]) : std::string();
  if (!config_file.empty()) {
    if (!std::filesystem::is_regular_file(config_file))  // as --config's check
      throw std::invalid_argument("--config: File does not exist: " + config_file);
    config = cli::read_build_config(config_file, BuildParams{});
    req.other_inputs.push_back({"--config", config_file});
    req.method_params = config.method_params;  // the keywords' go over them
  }
  BuildKeywords kw;
  sort_keywords(kwargs, req, kw);
  req.params = params_over(config.params, kw.params);
  req.backend = config.backend;
  for (const auto& [key, value] : kw.backend) set_backend_key(req.backend, key, value);
  check_thread_count(req.backend.threads);
  req.backend = cli::with_environment(req.backend);
  req.method_params.validate();
  if (!req.source.poses.empty() && req.source.origin) throw std::invalid_argument("give --poses or --origin, not both");
  req.source.frame = kw.frame ? kw.frame : config.frame;
  req.source.kitti_frame = req.params.preprocess.kitti_frame;
  req.resume.params = [config_file, given = kw.params](const BuildParams& stored) {
    const BuildParams base = config_file.empty() ? stored : cli::read_build_config(config_file, stored).params;
    return resumed_params(stored, params_over(base, given));
  };
  req.method_params_json = [](const MethodParams& params, const std::string& name) {
    return cli::method_params_json(params, name);
  };
  req.note = [](const std::string& line) { std::fprintf(stderr, "bgkmap: %s\n", line.c_str()); };
  req.omp_wait_policy = cli::omp_wait_policy();
  return req;
}

// `bgkmap build`'s pipeline and report through the library, in this process.
py::object build(const py::object& inputs, const std::string& method, const py::object& outputs,
                 const py::object& progress, const py::kwargs& kwargs) {
  if (!progress.is_none() && !PyCallable_Check(progress.ptr()))
    throw py::type_error("progress must be a callable progress(done, total), or None");
  BuildRequest req = build_request(method, kwargs);
  for (const std::filesystem::path& p : paths_of(inputs)) req.inputs.push_back(p.string());
  // Without an output the map goes to a temporary folder, as an OctoMap tree (the one format
  // every method writes).
  const TemporaryFolder folder;
  const std::vector<std::filesystem::path> outs =
      outputs.is_none() ? std::vector<std::filesystem::path>{folder.path() / "map.ot"} : paths_of(outputs);
  for (const std::filesystem::path& p : outs) {
    std::string name = p.string();
    if (const std::string problem = cli::map_output_extension()(name); !problem.empty())
      throw std::invalid_argument("--output: " + problem);
    req.outputs.push_back(p.string());
  }
  if (!progress.is_none())
    req.progress = [&progress](const Progress& p) {
      py::gil_scoped_acquire gil;
      call_progress(progress, p.done, p.total);
    };
  nlohmann::json report;
  {
    py::gil_scoped_release release;
    report = report_json(BuildSession(std::move(req)).run());
  }
  return to_python(report);
}

// ---- metrics ----------------------------------------------------------------------------------

eval::LabelledScores labelled(const py::object& labels_object, const py::object& scores_object) {
  const py::array labels_any = py::array::ensure(labels_object);
  const py::array scores_any = py::array::ensure(scores_object);
  if (!labels_any || labels_any.ndim() != 1) throw py::value_error("labels must be a 1-D array");
  if (!scores_any || scores_any.ndim() != 1) throw py::value_error("scores must be a 1-D array");
  if (labels_any.shape(0) != scores_any.shape(0))
    throw py::value_error("labels and scores differ in length (" + std::to_string(labels_any.shape(0)) + " and " +
                          std::to_string(scores_any.shape(0)) + ")");
  const char kind = labels_any.dtype().kind();
  if (kind != 'b' && kind != 'i' && kind != 'u') throw py::type_error("labels must be bool or integer, got " + dtype_of(labels_any));
  if (!holds_real_numbers(scores_any)) throw py::type_error("scores must hold integers or floats, got " + dtype_of(scores_any));
  const auto labels = converted<py::array_t<int64_t, py::array::c_style | py::array::forcecast>>(labels_any);
  const DoubleArray scores = converted<DoubleArray>(scores_any);
  eval::LabelledScores out;
  for (py::ssize_t i = 0; i < scores.shape(0); ++i) {
    const double s = scores.data()[i];
    if (std::isnan(s)) throw py::value_error("scores[" + std::to_string(i) + "] is NaN");
    const int64_t l = labels.data()[i];
    if (l != 0 && l != 1) throw py::value_error("labels[" + std::to_string(i) + "] is " + std::to_string(l) + ", not 0 or 1");
    (l ? out.positive : out.negative).push_back(s);
  }
  return out;
}

// The cell states, ray stops, method names and the exception the module's functions raise.
void bind_constants(py::module_& m) {
  py::register_exception<InputError>(m, "InputError", PyExc_ValueError);
  // A parameter out of range is named by its keyword (prob_hit), as Python spells it.
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const ParamError& e) {
      PyErr_SetString(PyExc_ValueError, e.as_keywords().c_str());
    }
  });
  m.attr("UNKNOWN") = static_cast<int>(CellState::kUnknown);
  m.attr("FREE") = static_cast<int>(CellState::kFree);
  m.attr("OCCUPIED") = static_cast<int>(CellState::kOccupied);
  m.attr("STOP_OCCUPIED") = static_cast<int>(RayStop::kOccupied);
  m.attr("STOP_UNKNOWN") = static_cast<int>(RayStop::kUnknown);
  m.attr("STOP_MAX_RANGE") = static_cast<int>(RayStop::kMaxRange);
  m.attr("STOP_MAP_END") = static_cast<int>(RayStop::kMapEnd);
  m.attr("METHODS") = py::tuple(py::cast(method_names()));
  m.attr("METHOD_PARAMS") = method_params_dict();
}

// bgkmap.Mapper: a map built and queried in this process.
void bind_mapper(py::module_& m) {
  const std::string mapper_doc =
      "Mapper(**params): an empty BGK-L map; Mapper(planar=True) a planar one, as `bgkmap build --2d`.\n\n"
      "Keywords are the `bgkmap build` flags with underscores (planar for --2d), defaults as there:\n" +
      keyword_doc() +
      "\nPoints go in as (N, 3) array-likes of numbers (metres; arrays of any int or float dtype, lists, tuples)\n"
      "in the world frame; NaN/Inf points are dropped and counted (counts()['dropped_nonfinite']), as\n"
      "`bgkmap build` does with such points in a PCD file. Paths are str or os.PathLike (pathlib.Path).\n"
      "Methods release the GIL while they work.";
  py::class_<PyMapper>(m, "Mapper", mapper_doc.c_str())
      .def(py::init(&PyMapper::from_keywords))
      .def("insert", &PyMapper::insert, py::arg("points"), py::arg("origin") = py::none(), py::kw_only(),
           py::arg("pose") = py::none(),
           "insert(points, origin) or insert(points, pose=T): adds one scan.\n\n"
           "points: (N, 3) numbers (m), world frame with origin (3,) the sensor position (m); or sensor frame\n"
           "with pose, a 4x4 rigid sensor-to-world transform (points become T @ [p, 1], the origin T[:3, 3]).\n"
           "NaN/Inf points are dropped and counted; a non-finite origin or pose is refused (ValueError).")
      .def("insert_file", &PyMapper::insert_file, py::arg("paths"), py::kw_only(), py::arg("poses") = py::none(),
           py::arg("origin") = py::none(), py::arg("frame") = py::none(), py::arg("progress") = py::none(),
           "insert_file(paths, poses=None, origin=None, frame=None, progress=None): adds every scan of a scan file\n"
           "or folder (any format `bgkmap build` reads; str or pathlib.Path), or of a list of them, in the order\n"
           "`bgkmap build` takes them; poses / origin (3,) in metres as --poses / --origin for inputs without a pose\n"
           "of their own (PLY, XYZ, PCD without a VIEWPOINT); frame 'world' or 'sensor' as --frame (it must agree\n"
           "with the Mapper's frame). As `bgkmap build --resume`, scans of these files the map already holds (same\n"
           "contents, by SHA-256) are passed over; save() records the ones it holds.\n"
           "progress: called as progress(done, total) before the first scan and as each is read: done the scans\n"
           "read in input order (held ones passed over included), total the scans the inputs hold (a log's\n"
           "estimated from the bytes read, exact at its end; None while not known). It runs without the map's\n"
           "lock (it may query the map); an exception it raises stops the insert, the scans before it staying.\n"
           "Returns the number of scans inserted.")
      .def("query", &PyMapper::query, py::arg("points"),
           "query(points) -> (alpha, beta): the Beta posterior of the cell holding each (N, 3) point (m), float64\n"
           "arrays (cells never observed give the prior). Non-finite points are refused.")
      .def(
          "mean",
          [](PyMapper& self, const py::object& points) {
            return self.per_point<double>(points, [](const BgkMap&, const CellPosterior& p) { return p.mean(); });
          },
          py::arg("points"), "mean(points) -> (N,) float64: posterior mean, the occupancy probability, at (N, 3) points (m)")
      .def(
          "variance",
          [](PyMapper& self, const py::object& points) {
            return self.per_point<double>(points, [](const BgkMap&, const CellPosterior& p) { return p.variance(); });
          },
          py::arg("points"), "variance(points) -> (N,) float64: posterior variance at (N, 3) points (m)")
      .def(
          "state",
          [](PyMapper& self, const py::object& points) {
            return self.per_point<uint8_t>(points, [](const BgkMap& map, const CellPosterior& p) {
              return static_cast<uint8_t>(p.state(map.params().classify));
            });
          },
          py::arg("points"),
          "state(points) -> (N,) uint8: bgkmap.UNKNOWN (0), FREE (1) or OCCUPIED (2) by the map's thresholds, at\n"
          "(N, 3) points (m)")
      .def("cells", &PyMapper::cells,
           "cells() -> (centres (M, 3) in metres, alpha (M,), beta (M,)), float64, for every cell with evidence, in\n"
           "the order of the .bgk file")
      .def("cast_rays", &PyMapper::cast_rays, py::arg("origins"), py::arg("directions"), py::arg("max_range") = 0.0,
           py::arg("unknown") = "stop",
           "cast_rays(origins, directions, max_range=0, unknown='stop') -> dict of arrays, one row per ray: the\n"
           "first occupied cell along each ray (`bgkmap query --rays`, docs/QUERIES.md). origins (m), directions (any\n"
           "length): (N, 3) numbers; max_range (m): a number or (N,), 0 for no limit; unknown: 'stop' at the first\n"
           "unknown cell or 'pass' through unknown cells. Returns hit (bool), centres (N, 3, m) of the cells where\n"
           "the rays stopped, distance (m)\n"
           "(to where the ray enters that cell; to the range's end or the map's edge when nothing stopped it),\n"
           "state (uint8, bgkmap.UNKNOWN/FREE/OCCUPIED), stop (uint8, bgkmap.STOP_OCCUPIED, STOP_UNKNOWN,\n"
           "STOP_MAX_RANGE, STOP_MAP_END). A planar map casts in its plane (z ignored).")
      .def(
          "cells_in_box",
          [](PyMapper& self, const py::object& lo, const py::object& hi, bool include_unobserved) {
            return self.box_cells(box_of(lo, hi), include_unobserved ? CellSelection::kAll : CellSelection::kWithEvidence);
          },
          py::arg("lo"), py::arg("hi"), py::kw_only(), py::arg("include_unobserved") = false,
          "cells_in_box(lo, hi, include_unobserved=False) -> dict of centres (M, 3, m), alpha, beta (float64) and\n"
          "state (uint8) of the cells whose centres lie in the box [lo, hi] (each (3,), m; a planar map ignores z):\n"
          "those with evidence, or with include_unobserved every cell, the unobserved at the prior. Block by\n"
          "block in key order (z, y, x), in each block x fastest.")
      .def(
          "occupied_cells",
          [](PyMapper& self, const py::object& lo, const py::object& hi) {
            return self.box_cells(box_of(lo, hi), CellSelection::kOccupied);
          },
          py::arg("lo") = py::none(), py::arg("hi") = py::none(),
          "occupied_cells(lo=None, hi=None) -> dict as cells_in_box: the cells the map calls occupied, of the\n"
          "whole map or of the box [lo, hi]")
      .def("save", &PyMapper::write, py::arg("path"), py::arg("ot_values") = "classified",
           "save(path, ot_values='classified'): writes the map (path: str or pathlib.Path), atomically: a .bgk keeps\n"
           "alpha, beta and the scans of files it holds (as export(), another extension writes that format)")
      .def("export", &PyMapper::export_band, py::arg("path"), py::arg("ot_values") = "classified", py::kw_only(),
           py::arg("z_min") = py::none(), py::arg("z_max") = py::none(),
           "export(path, ot_values='classified', z_min=None, z_max=None): writes the map in the format the extension\n"
           "names, atomically: .bgk, .ot, .bt (a .ot holds the cells the map classifies occupied or free, 'classified',\n"
           "as OctoMap's tools read them, or every cell's posterior mean, 'mean', for bgkmap eval), or as `bgkmap\n"
           "export` .pgm (+ .yaml beside it, ROS map_server; a 3-D map projected over the cells whose centre lies in\n"
           "[z_min, z_max] (m), default every height), .ply or .pcd (occupied cells with probability and variance)")
      .def("__repr__", &PyMapper::repr)
      .def_property_readonly("params", &PyMapper::params, "The map's parameters (dict, `bgkmap info`'s names)")
      .def("counts", &PyMapper::counts, "Counts so far (dict): scans, points_read, dropped_nonfinite, hits, ...")
      .def_property_readonly("backend", &PyMapper::backend, "The back end in use (dict: name, device, threads, note)");
}

// load(), set_max_memory(), read_scans() and build(): maps and scans from files, the build command.
void bind_files(py::module_& m) {
  m.def("load", &load, py::arg("path"),
        "load(path, backend='auto', threads=0, device='') -> Mapper: a native .bgk map (path: str or pathlib.Path); "
        "insert_file continues it "
        "exactly as `bgkmap build --resume` would (a map of --method bgk or counting is read, not continued: "
        "inserting into it raises ValueError).");
  m.def(
      "set_max_memory",
      [](const std::optional<std::string>& size) { set_memory_limit_bytes(size ? parse_byte_size(*size) : 0); },
      py::arg("size") = py::none(),
      "set_max_memory(size=None): the memory this process may use for mapping, as `--max-memory` (\"8G\",\n"
      "\"500M\"; None restores the default, half of physical memory): work that would go beyond it is refused before it\n"
      "starts, with a RuntimeError naming what needs how much. Process-wide: set it before mapping.");
  m.def("read_scans", &read_scans, py::arg("paths"), py::kw_only(), py::arg("poses") = py::none(),
        py::arg("origin") = py::none(), py::arg("frame") = py::none(),
        "read_scans(paths, poses=None, origin=None, frame=None) -> list of dicts (points (N, 3) float32, origin (3,),\n"
        "orientation (w, x, y, z), in_world_frame, source; lengths in metres), one per scan of every file `bgkmap build`\n"
        "reads (str or pathlib.Path; folders expanded). All the\n"
        "scans are held in memory: for long logs use Mapper.insert_file.");
  m.def("build", &build, py::arg("inputs"), py::arg("method") = "bgkl", py::arg("outputs") = py::none(),
        py::kw_only(), py::arg("progress") = py::none(),
        "build(inputs, method='bgkl', outputs=None, progress=None, **flags) -> report (dict)\n\n"
        "Runs `bgkmap build`'s pipeline (the library's BuildSession) in this process: scan files or folders (str\n"
        "or pathlib.Path) through one method\n"
        "(bgkmap.METHODS), maps written to `outputs` (a path or a list; format from the extension), the JSON\n"
        "report returned. Keywords are the command's flags with underscores and the same defaults (lengths in\n"
        "metres): build(..., max_range=8, ds=0.1, prob_hit=0.7, resume='old.bgk', config='p.yaml',\n"
        "skip_bad_inputs=True); True sets a bare flag, None or False leaves it out. progress: called as progress(done,\n"
        "total) each time the command's progress bar would move, phase by phase (the scans read, then e.g.\n"
        "gpom's prediction, each counted from 0; total None while not known); an exception it raises stops\n"
        "the build, which then writes no map. Errors carry the command's one-line messages (bad flags:\n"
        "ValueError).");
}

// view(): a map as an HTML page.
void bind_view(py::module_& m) {
  m.def(
      "view",
      [](const py::object& map_path, const py::object& output_path, size_t max_cells) {
        const std::string map = path_text(map_path), output = path_text(output_path);
        std::string name = output;
        if (const std::string problem = cli::view_output_extension()(name); !problem.empty())
          throw py::value_error("output: " + problem);
        viz::ViewStats stats;
        {
          py::gil_scoped_release release;
          check_output_path(output);
          stats = viz::write_view_html(output, viz::read_view_map(map), max_cells);
        }
        py::dict out;
        out["boxes"] = stats.cells;
        out["map_cells"] = stats.map_cells;
        out["merge_level"] = stats.reduction.level;
        out["min_probability"] = stats.reduction.min_probability;
        out["bytes"] = stats.bytes;
        return out;
      },
      py::arg("map"), py::arg("output"), py::arg("max_cells") = viz::kDefaultMaxViewCells,
      "view(map, output, max_cells=1000000) -> dict: `bgkmap view`: a .bgk, .ot or .bt map (paths: str or\n"
      "pathlib.Path) as one self-contained HTML page with a 3-D WebGL view of its occupied cells\n"
      "(docs/VIEWER.md). Returns boxes (in the page), map_cells (of probability >= 0.5), merge_level,\n"
      "min_probability (the slider's lower end), bytes.");
}

// auc(), average_precision(), nll(), metrics(), curves(): `bgkmap eval`'s scores.
void bind_eval(py::module_& m) {
  const double default_threshold = ClassifyParams{}.occupied_threshold;
  m.def(
      "auc", [](const py::object& l, const py::object& s) { return eval::roc_auc(labelled(l, s)); }, py::arg("labels"),
      py::arg("scores"), "auc(labels, scores): ROC AUC, tie-aware (NaN when a class is empty); labels 0/1 or bool");
  m.def(
      "average_precision", [](const py::object& l, const py::object& s) { return eval::average_precision(labelled(l, s)); },
      py::arg("labels"), py::arg("scores"), "average_precision(labels, scores): area under precision-recall");
  m.def(
      "nll", [](const py::object& l, const py::object& s) { return eval::mean_nll(labelled(l, s)); }, py::arg("labels"),
      py::arg("scores"), "nll(labels, scores): mean negative log-likelihood, probabilities clamped to [1e-6, 1-1e-6]");
  m.def(
      "metrics",
      [](const py::object& l, const py::object& s, double threshold) {
        const eval::BinaryMetrics b = eval::compute_metrics(labelled(l, s), threshold);
        py::dict d;
        d["auc"] = b.auc;
        d["average_precision"] = b.average_precision;
        d["nll"] = b.nll;
        d["accuracy"] = b.accuracy;
        d["precision"] = b.precision;
        d["recall"] = b.recall;
        d["n_positive"] = b.n_positive;
        d["n_negative"] = b.n_negative;
        return d;
      },
      py::arg("labels"), py::arg("scores"), py::arg("occupied_threshold") = default_threshold,
      "metrics(labels, scores, occupied_threshold) -> dict as `bgkmap eval` reports: auc, average_precision,\n"
      "nll, accuracy, precision, recall (score > threshold predicts occupied), n_positive, n_negative");
  m.def(
      "curves",
      [](const py::object& l, const py::object& s) {
        eval::Curves c = eval::compute_curves(labelled(l, s));
        py::dict d;
        d["fpr"] = vector_array(std::move(c.fpr));
        d["tpr"] = vector_array(std::move(c.tpr));
        d["recall"] = vector_array(std::move(c.recall));
        d["precision"] = vector_array(std::move(c.precision));
        return d;
      },
      py::arg("labels"), py::arg("scores"), "curves(labels, scores) -> dict of arrays: fpr, tpr (ROC), recall, precision");
}

// tune(): `bgkmap tune` in this process.
void bind_tune(py::module_& m) {
  m.def(
      "tune",
      [](const py::object& inputs, const std::string& method, const py::object& output, const py::kwargs& kwargs) {
        const TemporaryFolder folder;
        const std::filesystem::path report = folder.path() / "tune.json";
        const std::string yaml = output.is_none() ? (folder.path() / "params.yaml").string() : py::str(output).cast<std::string>();
        std::vector<std::string> args = {"bgkmap", "tune", "--quiet", "--method", method, "--report", report.string(), "-o", yaml};
        for (const std::filesystem::path& p : paths_of(inputs)) args.push_back(p.string());
        add_flags(args, kwargs);
        run_command(args, cli::add_tune_command);
        std::ifstream in(report);
        nlohmann::json r = nlohmann::json::parse(in);
        nlohmann::json chosen = nlohmann::json::object();
        for (const nlohmann::json& p : r["parameters"]) chosen[p["name"].get<std::string>()] = p["chosen"];
        return py::make_tuple(to_python(chosen), to_python(r["trials"]), to_python(r));
      },
      py::arg("inputs"), py::arg("method") = "bgkl", py::arg("output") = py::none(),
      "tune(inputs, method='bgkl', output=None, **flags) -> (parameters, trials, report)\n\n"
      "Runs `bgkmap tune` in this process (docs/TUNE.md): the method's parameters chosen by held-out likelihood.\n"
      "parameters: {name: chosen value}; trials: the report's list (values, phase, objective, search metrics);\n"
      "report: the whole JSON report (the given and tuned scores on both splits). `output` writes the YAML that\n"
      "build(config=...) takes. Keywords are the command's flags: tune(scans, holdout=0.1, split='scans',\n"
      "budget=10, max_range=8). Errors carry the command's one-line messages (bad flags: ValueError).");
}

}  // namespace

}  // namespace bgkmap::python

using namespace bgkmap;
using namespace bgkmap::python;

PYBIND11_MODULE(bgkmap, m) {
  m.doc() =
      "BGK-L occupancy maps from range scans (Bayesian generalized kernel inference), on OpenCL or OpenMP.\n\n"
      "Mapper builds and queries a map from numpy arrays or scan files; build() runs `bgkmap build` with any\n"
      "--method and returns its JSON report as a dict; load() reads a .bgk map; view() writes a map as an HTML\n"
      "page with a 3-D view (`bgkmap view`); auc(), average_precision(), nll(), metrics() and curves() score\n"
      "occupancy predictions as `bgkmap eval` does. See docs/PYTHON.md.";
  m.attr("__version__") = BGKMAP_VERSION;
  bind_constants(m);
  bind_mapper(m);
  bind_files(m);
  bind_view(m);
  bind_eval(m);
  bind_tune(m);
}
