// Scene files (YAML) in and out. The only translation unit that includes yaml-cpp.
#include <yaml-cpp/yaml.h>

#include <charconv>
#include <fstream>
#include <set>
#include <sstream>
#include <stdexcept>
#include <type_traits>

#include "bgkmap/io/atomic_file.hpp"
#include "bgkmap/io/errors.hpp"
#include "bgkmap/sim/spec.hpp"

namespace bgkmap::sim {

namespace {

// A problem at a node: reported as "line N: what".
struct SchemaError : std::runtime_error {
  SchemaError(const YAML::Node& node, const std::string& what)
      : std::runtime_error(node.Mark().is_null() ? what : "line " + std::to_string(node.Mark().line + 1) + ": " + what) {}
};

void require_map(const YAML::Node& node, const std::string& what, const std::set<std::string>& allowed) {
  if (!node.IsMap()) throw SchemaError(node, what + " must be a mapping");
  for (const auto& kv : node) {
    const std::string key = kv.first.as<std::string>();
    if (!allowed.count(key)) {
      std::string list;
      for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
      throw SchemaError(kv.first, "unknown key '" + key + "' in " + what + " (expected " + list + ")");
    }
  }
}

YAML::Node required(const YAML::Node& map, const char* key, const std::string& what) {
  const YAML::Node n = map[key];
  if (!n) throw SchemaError(map, what + " needs '" + key + "'");
  return n;
}

template <typename T>
T scalar(const YAML::Node& node, const std::string& what) {
  if (!node.IsScalar()) throw SchemaError(node, what + " must be a single value");
  try {
    return node.as<T>();
  } catch (const YAML::Exception&) {
    throw SchemaError(node, what + ": cannot read '" + node.Scalar() + "'");
  }
}

template <typename T>
T optional_scalar(const YAML::Node& map, const char* key, T fallback) {
  const YAML::Node n = map[key];
  return n ? scalar<T>(n, key) : fallback;
}

std::vector<double> numbers(const YAML::Node& node, size_t count, const std::string& what) {
  if (!node.IsSequence() || (count > 0 && node.size() != count))
    throw SchemaError(node, what + " must be a list of " + std::to_string(count) + " numbers");
  std::vector<double> out;
  for (const auto& v : node) out.push_back(scalar<double>(v, what));
  return out;
}

Vec3d vec3(const YAML::Node& node, const std::string& what) {
  const auto v = numbers(node, 3, what);
  return {v[0], v[1], v[2]};
}

Box3d parse_bounds(const YAML::Node& node) {
  require_map(node, "bounds", {"min", "max"});
  const Box3d b{vec3(required(node, "min", "bounds"), "bounds.min"), vec3(required(node, "max", "bounds"), "bounds.max")};
  if (!(b.min.x < b.max.x && b.min.y < b.max.y && b.min.z < b.max.z))
    throw SchemaError(node, "bounds.min must be below bounds.max on every axis");
  return b;
}

Primitive parse_primitive(const YAML::Node& node) {
  if (!node.IsMap()) throw SchemaError(node, "a primitive must be a mapping with a 'type'");
  const std::string type = scalar<std::string>(required(node, "type", "a primitive"), "type");
  try {
    if (type == "box") {
      require_map(node, "box", {"type", "center", "size", "rpy_deg"});
      const Vec3d rpy = node["rpy_deg"] ? vec3(node["rpy_deg"], "rpy_deg") : Vec3d{};
      return Box(vec3(required(node, "center", "box"), "center"), vec3(required(node, "size", "box"), "size"), rpy);
    }
    if (type == "cylinder") {
      require_map(node, "cylinder", {"type", "base", "top", "radius"});
      return Cylinder(vec3(required(node, "base", "cylinder"), "base"), vec3(required(node, "top", "cylinder"), "top"),
                      scalar<double>(required(node, "radius", "cylinder"), "radius"));
    }
    if (type == "sphere") {
      require_map(node, "sphere", {"type", "center", "radius"});
      return Sphere(vec3(required(node, "center", "sphere"), "center"),
                    scalar<double>(required(node, "radius", "sphere"), "radius"));
    }
    if (type == "plane") {
      require_map(node, "plane", {"type", "point", "normal"});
      return HalfSpace(vec3(required(node, "point", "plane"), "point"), vec3(required(node, "normal", "plane"), "normal"));
    }
    if (type == "heightfield") {
      require_map(node, "heightfield", {"type", "origin", "cell", "base_z", "heights"});
      const auto origin = numbers(required(node, "origin", "heightfield"), 2, "origin");
      const YAML::Node rows = required(node, "heights", "heightfield");
      if (!rows.IsSequence()) throw SchemaError(rows, "heights must be a list of rows");
      std::vector<std::vector<double>> heights;
      for (const auto& row : rows) heights.push_back(numbers(row, 0, "a heights row"));
      return HeightField(origin[0], origin[1], scalar<double>(required(node, "cell", "heightfield"), "cell"),
                         scalar<double>(required(node, "base_z", "heightfield"), "base_z"), std::move(heights));
    }
  } catch (const std::invalid_argument& e) {
    throw SchemaError(node, e.what());
  }
  throw SchemaError(node, "unknown primitive type '" + type + "' (expected box, cylinder, sphere, plane, heightfield)");
}

DynamicObject parse_dynamic(const YAML::Node& node, size_t index) {
  require_map(node, "a dynamic object", {"name", "shape", "appear", "disappear", "path", "closed", "speed"});
  DynamicObject d;
  d.name = optional_scalar<std::string>(node, "name", "object " + std::to_string(index));
  d.shape = parse_primitive(required(node, "shape", "a dynamic object"));
  d.appear = optional_scalar(node, "appear", 0);
  if (node["disappear"]) d.disappear = scalar<int>(node["disappear"], "disappear");
  if (node["path"]) {
    if (!node["path"].IsSequence()) throw SchemaError(node["path"], "path must be a list of [x, y, z] points");
    for (const auto& p : node["path"]) d.path.push_back(vec3(p, "a path point"));
  }
  d.closed = optional_scalar(node, "closed", false);
  d.speed_m_per_scan = optional_scalar(node, "speed", 0.0);
  try {
    d.validate();
  } catch (const std::invalid_argument& e) {
    throw SchemaError(node, e.what());
  }
  return d;
}

SensorModel parse_sensor(const YAML::Node& node) {
  try {
    if (node.IsScalar()) return sensor_preset(scalar<std::string>(node, "sensor"));
  } catch (const std::invalid_argument& e) {
    throw SchemaError(node, e.what());
  }
  require_map(node, "sensor",
              {"preset", "name", "kind", "rings", "elevation_min_deg", "elevation_max_deg", "azimuth_resolution_deg",
               "horizontal_fov_deg", "width", "height", "vertical_fov_deg", "max_range", "range_noise_sigma",
               "dropout"});
  SensorModel s = node["preset"] ? sensor_preset(scalar<std::string>(node["preset"], "preset")) : SensorModel{};
  if (node["kind"]) s.kind = sensor_kind_from_string(scalar<std::string>(node["kind"], "kind"));
  s.name = optional_scalar<std::string>(node, "name", node["preset"] ? s.name : "custom");
  s.rings = optional_scalar(node, "rings", s.rings);
  s.elevation_min_deg = optional_scalar(node, "elevation_min_deg", s.elevation_min_deg);
  s.elevation_max_deg = optional_scalar(node, "elevation_max_deg", s.elevation_max_deg);
  s.azimuth_resolution_deg = optional_scalar(node, "azimuth_resolution_deg", s.azimuth_resolution_deg);
  s.horizontal_fov_deg = optional_scalar(node, "horizontal_fov_deg", s.horizontal_fov_deg);
  s.width = optional_scalar(node, "width", s.width);
  s.height = optional_scalar(node, "height", s.height);
  s.vertical_fov_deg = optional_scalar(node, "vertical_fov_deg", s.vertical_fov_deg);
  s.max_range_m = optional_scalar(node, "max_range", s.max_range_m);
  s.range_noise_sigma_m = optional_scalar(node, "range_noise_sigma", s.range_noise_sigma_m);
  s.dropout = optional_scalar(node, "dropout", s.dropout);
  try {
    s.validate();
  } catch (const std::invalid_argument& e) {
    throw SchemaError(node, e.what());
  }
  return s;
}

Waypoint parse_waypoint(const YAML::Node& node) {
  if (node.IsSequence()) return {vec3(node, "waypoint"), std::nullopt};
  require_map(node, "waypoint", {"position", "yaw_deg"});
  Waypoint w{vec3(required(node, "position", "waypoint"), "position"), std::nullopt};
  if (node["yaw_deg"]) w.yaw_deg = scalar<double>(node["yaw_deg"], "yaw_deg");
  return w;
}

Trajectory parse_trajectory(const YAML::Node& node) {
  require_map(node, "trajectory", {"scans", "closed", "waypoints", "station"});
  Trajectory t;
  t.scans = optional_scalar(node, "scans", 1);
  t.closed = optional_scalar(node, "closed", false);
  if (node["station"] && node["waypoints"]) throw SchemaError(node, "trajectory has both 'station' and 'waypoints'");
  if (node["station"]) {
    t.waypoints.push_back(parse_waypoint(node["station"]));
  } else {
    const YAML::Node list = required(node, "waypoints", "trajectory (or 'station')");
    if (!list.IsSequence() || list.size() == 0) throw SchemaError(list, "waypoints must be a non-empty list");
    for (const auto& w : list) t.waypoints.push_back(parse_waypoint(w));
  }
  try {
    t.validate();
  } catch (const std::invalid_argument& e) {
    throw SchemaError(node, e.what());
  }
  return t;
}

SimulationSpec parse_root(const YAML::Node& root, const std::string& default_name) {
  require_map(root, "the scene file", {"name", "seed", "truth_resolution", "bounds", "sensor", "trajectory", "primitives", "dynamic"});
  SimulationSpec spec;
  spec.name = optional_scalar<std::string>(root, "name", default_name);
  spec.seed = optional_scalar<uint64_t>(root, "seed", spec.seed);
  spec.truth_resolution_m = optional_scalar(root, "truth_resolution", spec.truth_resolution_m);
  if (root["bounds"]) spec.scene.bounds = parse_bounds(root["bounds"]);
  spec.sensor = root["sensor"] ? parse_sensor(root["sensor"]) : sensor_preset("vlp16");
  spec.trajectory = parse_trajectory(required(root, "trajectory", "the scene file"));
  const YAML::Node prims = required(root, "primitives", "the scene file");
  if (!prims.IsSequence() || prims.size() == 0) throw SchemaError(prims, "primitives must be a non-empty list");
  for (const auto& p : prims) spec.scene.primitives.push_back(parse_primitive(p));
  if (const YAML::Node dynamic = root["dynamic"]) {
    if (!dynamic.IsSequence()) throw SchemaError(dynamic, "dynamic must be a list of objects");
    for (const auto& d : dynamic) spec.scene.dynamic.push_back(parse_dynamic(d, spec.scene.dynamic.size()));
  }
  try {
    spec.validate();
  } catch (const std::invalid_argument& e) {
    throw SchemaError(root, e.what());
  }
  return spec;
}

// ---- Writing

// Shortest decimal that reads back as the same double.
std::string number(double v) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

void emit_vec(YAML::Emitter& out, const char* key, const Vec3d& v) {
  out << YAML::Key << key << YAML::Value << YAML::Flow << YAML::BeginSeq << number(v.x) << number(v.y) << number(v.z)
      << YAML::EndSeq;
}

void emit_primitive(YAML::Emitter& out, const Primitive& primitive) {
  out << YAML::Flow << YAML::BeginMap << YAML::Key << "type" << YAML::Value << type_name(primitive);
  std::visit(
      [&](const auto& s) {
        using T = std::decay_t<decltype(s)>;
        if constexpr (std::is_same_v<T, Box>) {
          emit_vec(out, "center", s.center());
          emit_vec(out, "size", s.size());
          const Vec3d r = s.rpy_deg();
          if (r.x != 0 || r.y != 0 || r.z != 0) emit_vec(out, "rpy_deg", r);
        } else if constexpr (std::is_same_v<T, Cylinder>) {
          emit_vec(out, "base", s.base());
          emit_vec(out, "top", s.top());
          out << YAML::Key << "radius" << YAML::Value << number(s.radius());
        } else if constexpr (std::is_same_v<T, Sphere>) {
          emit_vec(out, "center", s.center());
          out << YAML::Key << "radius" << YAML::Value << number(s.radius());
        } else if constexpr (std::is_same_v<T, HalfSpace>) {
          emit_vec(out, "point", s.point());
          emit_vec(out, "normal", s.normal());
        } else {
          out << YAML::Key << "origin" << YAML::Value << YAML::BeginSeq << number(s.origin_x()) << number(s.origin_y())
              << YAML::EndSeq;
          out << YAML::Key << "cell" << YAML::Value << number(s.cell());
          out << YAML::Key << "base_z" << YAML::Value << number(s.base_z());
          out << YAML::Key << "heights" << YAML::Value << YAML::BeginSeq;
          for (const auto& row : s.heights()) {
            out << YAML::BeginSeq;
            for (double h : row) out << number(h);
            out << YAML::EndSeq;
          }
          out << YAML::EndSeq;
        }
      },
      primitive);
  out << YAML::EndMap;
}

void emit_dynamic(YAML::Emitter& out, const DynamicObject& d) {
  out << YAML::BeginMap << YAML::Key << "name" << YAML::Value << d.name;
  out << YAML::Key << "shape" << YAML::Value;
  emit_primitive(out, d.shape);
  out << YAML::Key << "appear" << YAML::Value << d.appear;
  if (d.disappear) out << YAML::Key << "disappear" << YAML::Value << *d.disappear;
  if (!d.path.empty()) {
    out << YAML::Key << "path" << YAML::Value << YAML::Flow << YAML::BeginSeq;
    for (const Vec3d& p : d.path) out << YAML::Flow << YAML::BeginSeq << number(p.x) << number(p.y) << number(p.z) << YAML::EndSeq;
    out << YAML::EndSeq;
    out << YAML::Key << "closed" << YAML::Value << d.closed;
    out << YAML::Key << "speed" << YAML::Value << number(d.speed_m_per_scan);
  }
  out << YAML::EndMap;
}

void emit_sensor(YAML::Emitter& out, const SensorModel& s) {
  out << YAML::BeginMap;
  out << YAML::Key << "name" << YAML::Value << s.name;
  out << YAML::Key << "kind" << YAML::Value << to_string(s.kind);
  if (s.kind == SensorKind::kSpinning) {
    out << YAML::Key << "rings" << YAML::Value << s.rings;
    out << YAML::Key << "elevation_min_deg" << YAML::Value << number(s.elevation_min_deg);
    out << YAML::Key << "elevation_max_deg" << YAML::Value << number(s.elevation_max_deg);
    out << YAML::Key << "azimuth_resolution_deg" << YAML::Value << number(s.azimuth_resolution_deg);
  } else {
    out << YAML::Key << "width" << YAML::Value << s.width;
    out << YAML::Key << "height" << YAML::Value << s.height;
    out << YAML::Key << "vertical_fov_deg" << YAML::Value << number(s.vertical_fov_deg);
  }
  out << YAML::Key << "horizontal_fov_deg" << YAML::Value << number(s.horizontal_fov_deg);
  out << YAML::Key << "max_range" << YAML::Value << number(s.max_range_m);
  out << YAML::Key << "range_noise_sigma" << YAML::Value << number(s.range_noise_sigma_m);
  out << YAML::Key << "dropout" << YAML::Value << number(s.dropout);
  out << YAML::EndMap;
}

void emit_waypoint(YAML::Emitter& out, const Waypoint& w) {
  out << YAML::Flow << YAML::BeginMap;
  emit_vec(out, "position", w.position);
  if (w.yaw_deg) out << YAML::Key << "yaw_deg" << YAML::Value << number(*w.yaw_deg);
  out << YAML::EndMap;
}

void emit_trajectory(YAML::Emitter& out, const Trajectory& t) {
  out << YAML::BeginMap;
  out << YAML::Key << "scans" << YAML::Value << t.scans;
  if (t.waypoints.size() == 1) {
    out << YAML::Key << "station" << YAML::Value;
    emit_waypoint(out, t.waypoints[0]);
  } else {
    out << YAML::Key << "closed" << YAML::Value << t.closed;
    out << YAML::Key << "waypoints" << YAML::Value << YAML::BeginSeq;
    for (const auto& w : t.waypoints) emit_waypoint(out, w);
    out << YAML::EndSeq;
  }
  out << YAML::EndMap;
}

}  // namespace

namespace {
// Runs parse(root) on YAML text; every failure becomes one InputError line naming the source.
template <typename Parse>
auto parse_yaml(const std::string& yaml_text, const std::string& source_name, Parse parse) {
  try {
    return parse(YAML::Load(yaml_text));
  } catch (const YAML::Exception& e) {
    throw InputError(source_name, "not valid YAML (line " + std::to_string(e.mark.line + 1) + ": " + e.msg + ")");
  } catch (const std::runtime_error& e) {
    throw InputError(source_name, e.what());
  } catch (const std::invalid_argument& e) {
    throw InputError(source_name, e.what());
  }
}

std::string read_text(const std::filesystem::path& file, const char* what) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw InputError(file, std::string("cannot open the ") + what);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}
}  // namespace

SimulationSpec parse_spec(const std::string& yaml_text, const std::string& source_name) {
  return parse_yaml(yaml_text, source_name, [&](const YAML::Node& root) {
    return parse_root(root, std::filesystem::path(source_name).stem().string());
  });
}

SimulationSpec load_spec(const std::filesystem::path& file) {
  return parse_spec(read_text(file, "scene file"), file.string());
}

SensorModel load_sensor(const std::filesystem::path& file) {
  return parse_yaml(read_text(file, "sensor file"), file.string(), [](const YAML::Node& root) { return parse_sensor(root); });
}

std::string spec_to_yaml(const SimulationSpec& spec) {
  YAML::Emitter out;
  out << YAML::Comment("bgkmap simulation scene (docs/SIMULATOR.md); `bgkmap simulate` on this file reproduces the run");
  out << YAML::BeginMap;
  out << YAML::Key << "name" << YAML::Value << spec.name;
  out << YAML::Key << "seed" << YAML::Value << spec.seed;
  out << YAML::Key << "truth_resolution" << YAML::Value << number(spec.truth_resolution_m);
  if (spec.scene.bounds) {
    out << YAML::Key << "bounds" << YAML::Value << YAML::Flow << YAML::BeginMap;
    emit_vec(out, "min", spec.scene.bounds->min);
    emit_vec(out, "max", spec.scene.bounds->max);
    out << YAML::EndMap;
  }
  out << YAML::Key << "sensor" << YAML::Value;
  emit_sensor(out, spec.sensor);
  out << YAML::Key << "trajectory" << YAML::Value;
  emit_trajectory(out, spec.trajectory);
  out << YAML::Key << "primitives" << YAML::Value << YAML::BeginSeq;
  for (const auto& p : spec.scene.primitives) emit_primitive(out, p);
  out << YAML::EndSeq;
  if (!spec.scene.dynamic.empty()) {
    out << YAML::Key << "dynamic" << YAML::Value << YAML::BeginSeq;
    for (const auto& d : spec.scene.dynamic) emit_dynamic(out, d);
    out << YAML::EndSeq;
  }
  out << YAML::EndMap;
  return std::string(out.c_str()) + "\n";
}

void save_spec(const std::filesystem::path& file, const SimulationSpec& spec) {
  const std::string text = spec_to_yaml(spec);
  write_file_atomically(file, [&](std::ostream& os) { os << text; });
}

}  // namespace bgkmap::sim
