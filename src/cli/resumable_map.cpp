#include "cli/resumable_map.hpp"

#include <cstdio>
#include <filesystem>
#include <optional>
#include <stdexcept>
#include <utility>

#include "bgkmap/io/atomic_file.hpp"
#include "bgkmap/io/errors.hpp"
#include "bgkmap/io/map_io.hpp"
#include "cli/output_names.hpp"
#include "core/stage_clock.hpp"

namespace bgkmap::cli {

namespace {

namespace fs = std::filesystem;

bool same_file(const fs::path& a, const fs::path& b) {
  std::error_code ec_a, ec_b;
  const fs::path ca = fs::weakly_canonical(a, ec_a), cb = fs::weakly_canonical(b, ec_b);
  return !ec_a && !ec_b && ca == cb;
}

bool is_native(const std::string& file) { return map_format_from_path(file) == MapFormat::kNative; }

}  // namespace

void ResumeOptions::add_to(CLI::App& cmd) {
  cmd.add_option("--resume", resume,
                 "Continue a native .bgk map: its parameters; the scans it already holds (same file contents) are "
                 "skipped (--method bgkl only). Under mpirun: the shard folder of an interrupted run, continued "
                 "from its last complete checkpoint (from the first scan if it wrote none)");
  cmd.add_option("--checkpoint-every", every,
                 "Write the map atomically every N scans (to --checkpoint, else the first .bgk output), recording "
                 "the scans it holds: after a crash, the same command with --resume MAP.bgk finishes the same map. "
                 "Under mpirun: every rank's shard, in the shard folder")
      ->check(CLI::Validator(  // a uint64: "-1" would wrap to 2^64 - 1
          [](std::string& value) {
            return value.find_first_not_of("0123456789") == std::string::npos && !value.empty()
                       ? std::string()
                       : "'" + value + "' is not a count of scans (0 = none)";
          },
          "N"));
  cmd.add_option("--checkpoint", checkpoint, "Where --checkpoint-every writes (a .bgk path)")
      ->check(output_extension({".bgk"}, "a checkpoint is a native .bgk map"));
}

ResumableMap::ResumableMap(ResumeOptions options, const std::vector<std::string>& outputs, const std::string& method)
    : options_(std::move(options)) {
  if (!options_.checkpoint.empty() && options_.every == 0)
    throw std::invalid_argument("--checkpoint needs --checkpoint-every N");
  if (method != "bgkl") {
    if (!options_.resume.empty())
      throw std::invalid_argument("--resume continues a BGK-L map: it cannot be used with --method " + method);
    if (options_.every > 0)
      throw std::invalid_argument("--checkpoint-every writes a BGK-L map: it cannot be used with --method " + method);
    return;
  }
  if (options_.every == 0) return;
  if (options_.checkpoint.empty()) {
    for (const std::string& out : outputs) {
      if (is_native(out)) {
        options_.checkpoint = out;
        break;
      }
    }
    if (options_.checkpoint.empty())
      throw std::invalid_argument("--checkpoint-every needs a .bgk output (-o MAP.bgk) or --checkpoint MAP.bgk");
  }
  check_output_path(options_.checkpoint);
}

std::unique_ptr<MappingMethod> ResumableMap::make_method(const BuildOptions& options, const BackendOptions& backend,
                                                         ScanSource& source) {
  std::optional<NativeMapFile> stored;
  if (!options_.resume.empty()) {
    std::error_code ec;
    if (!options_.checkpoint.empty() && !fs::exists(options_.resume, ec) && same_file(options_.resume, options_.checkpoint))
      std::fprintf(stderr, "bgkmap: no checkpoint at %s yet: building from the first scan\n", options_.resume.c_str());
    else
      stored = read_native_map_file(options_.resume);
    if (stored && stored->method != "bgkl")
      throw InputError(options_.resume, "built by --method " + stored->method +
                                            ": --resume continues a BGK-L map (its alpha and beta mean other evidence)");
  }
  std::unique_ptr<Integrator> integrator = make_integrator(backend);
  std::unique_ptr<Mapper> mapper;
  if (stored) {
    const BuildParams params = options.resolve_params_for_resume(stored->map.params());
    stored->map.set_classify(params.classify);
    mapper = std::make_unique<Mapper>(std::move(stored->map), std::move(integrator));
    held_ = HeldInputs(std::move(stored->held));
    const std::vector<uint64_t> held = held_.match(source.files());
    for (const uint64_t n : held) already_held_ += n;
    source.skip_held(held);
    std::fprintf(stderr, "bgkmap: %s holds %llu scan%s of these inputs already: %s\n", options_.resume.c_str(),
                 static_cast<unsigned long long>(already_held_), already_held_ == 1 ? "" : "s",
                 already_held_ ? "skipping them" : "adding every scan");
  } else {
    mapper = std::make_unique<Mapper>(options.resolve_params(), std::move(integrator));
  }
  mapper_ = mapper.get();
  return make_bgkl_method(std::move(mapper));
}

void ResumableMap::inserted(const ScanSource& source, size_t file, uint64_t scan) {
  if (!mapper_) return;
  held_.add(source.files(), file, scan);
  ++inserted_;
  if (options_.every == 0 || inserted_ % options_.every != 0) return;
  const Clock::time_point t0 = Clock::now();
  write_native_map(options_.checkpoint, mapper_->map(), held_.records());
  checkpoint_s_ += seconds_since(t0);
  ++checkpoints_;
}

bool ResumableMap::write(const std::string& output) {
  if (!mapper_ || !is_native(output)) return false;
  write_native_map(output, mapper_->map(), held_.records());
  return true;
}

void ResumableMap::add_to_report(nlohmann::json& report) const {
  report["resumed_from"] = options_.resume;
  report["checkpoint"] = {{"path", options_.checkpoint}, {"every", options_.every}, {"written", checkpoints_}};
  report["counts"]["scans_already_held"] = already_held_;
  report["timing"]["checkpoint_s"] = checkpoint_s_;
}

}  // namespace bgkmap::cli
