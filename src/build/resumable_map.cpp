#include "build/resumable_map.hpp"

#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <stdexcept>
#include <utility>

#include "bgkmap/io/atomic_file.hpp"
#include "bgkmap/io/errors.hpp"
#include "bgkmap/io/map_io.hpp"
#include "core/stage_clock.hpp"

namespace bgkmap {

namespace {

namespace fs = std::filesystem;

bool same_file(const fs::path& a, const fs::path& b) {
  std::error_code ec_a, ec_b;
  const fs::path ca = fs::weakly_canonical(a, ec_a), cb = fs::weakly_canonical(b, ec_b);
  return !ec_a && !ec_b && ca == cb;
}

bool is_native(const std::string& file) { return map_format_from_path(file) == MapFormat::kNative; }

std::string number_text(double v) { return v == 0 ? std::string("0 (off)") : nlohmann::json(v).dump(); }

}  // namespace

ResumableMap::ResumableMap(ResumeSettings settings, const std::vector<std::string>& outputs, const std::string& method)
    : settings_(std::move(settings)) {
  if (!settings_.checkpoint.empty() && settings_.every == 0)
    throw std::invalid_argument("--checkpoint needs --checkpoint-every N");
  if (method != "bgkl") {
    if (!settings_.resume.empty())
      throw std::invalid_argument("--resume continues a BGK-L map: it cannot be used with --method " + method);
    if (settings_.every > 0)
      throw std::invalid_argument("--checkpoint-every writes a BGK-L map: it cannot be used with --method " + method);
    return;
  }
  if (settings_.every == 0) return;
  if (settings_.checkpoint.empty()) {
    for (const std::string& out : outputs) {
      if (is_native(out)) {
        settings_.checkpoint = out;
        break;
      }
    }
    if (settings_.checkpoint.empty())
      throw std::invalid_argument("--checkpoint-every needs a .bgk output (-o MAP.bgk) or --checkpoint MAP.bgk");
  }
  check_output_path(settings_.checkpoint);
}

std::unique_ptr<MappingMethod> ResumableMap::make_method(const BuildParams& params, double forget_half_life,
                                                         const BackendOptions& backend, ScanSource& source,
                                                         const std::function<void(const std::string&)>& note) {
  std::optional<NativeMapFile> stored;
  if (!settings_.resume.empty()) {
    std::error_code ec;
    if (!settings_.checkpoint.empty() && !fs::exists(settings_.resume, ec) && same_file(settings_.resume, settings_.checkpoint))
      note("no checkpoint at " + settings_.resume + " yet: building from the first scan");
    else
      stored = read_native_map_file(settings_.resume, StoredTime::kAsStored);
    if (stored && stored->method != "bgkl")
      throw InputError(settings_.resume, "built by --method " + stored->method +
                                            ": --resume continues a BGK-L map (its alpha and beta mean other evidence)");
  }
  std::unique_ptr<Integrator> integrator = make_integrator(backend);
  std::unique_ptr<Mapper> mapper;
  if (stored) {
    const double stored_half_life = stored->map.forgetting().half_life_scans;
    if (stored_half_life != forget_half_life)
      throw std::invalid_argument("cannot change 'forget-half-life' when resuming a map (stored " +
                                  number_text(stored_half_life) + ", asked " + number_text(forget_half_life) +
                                  "): give the build's --forget-half-life again");
    const BuildParams& stored_params = stored->map.params();
    BuildParams wanted = stored_params;
    wanted.classify = params.classify;
    const BuildParams resumed =
        settings_.params ? settings_.params(stored_params) : resumed_params(stored_params, wanted);
    stored->map.set_classify(resumed.classify);
    mapper = std::make_unique<Mapper>(std::move(stored->map), std::move(integrator));
    held_ = HeldInputs(std::move(stored->held));
    const std::vector<uint64_t> held = held_.match(source.files());
    for (const uint64_t n : held) already_held_ += n;
    source.skip_held(held);
    note(settings_.resume + " holds " + std::to_string(already_held_) + " scan" + (already_held_ == 1 ? "" : "s") +
         " of these inputs already: " + (already_held_ ? "skipping them" : "adding every scan"));
  } else {
    mapper = std::make_unique<Mapper>(params, std::move(integrator));
    mapper->set_forget_half_life(forget_half_life);
  }
  mapper_ = mapper.get();
  return make_bgkl_method(std::move(mapper));
}

void ResumableMap::inserted(const ScanSource& source, size_t file, uint64_t scan) {
  if (!mapper_) return;
  held_.add(source.files(), file, scan);
  ++inserted_;
  if (settings_.every == 0 || inserted_ % settings_.every != 0) return;
  const Clock::time_point t0 = Clock::now();
  write_native_map(settings_.checkpoint, mapper_->lazy_map(), held_.records());
  checkpoint_s_ += seconds_since(t0);
  ++checkpoints_;
}

bool ResumableMap::write(const std::string& output) {
  if (!mapper_ || !is_native(output)) return false;
  write_native_map(output, mapper_->lazy_map(), held_.records());
  return true;
}

void ResumableMap::add_to(BuildReport& report) const {
  report.resumed_from = settings_.resume;
  report.checkpoint = settings_.checkpoint;
  report.checkpoint_every = settings_.every;
  report.checkpoints_written = checkpoints_;
  report.scans_already_held = already_held_;
  report.checkpoint_s = checkpoint_s_;
}

}  // namespace bgkmap
