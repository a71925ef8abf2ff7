// bgkmap merge: one map from the shards of a distributed build.
#include <filesystem>
#include <stdexcept>
#include <string>
#include <system_error>
#include <vector>

#include "bgkmap/dist/shards.hpp"
#include "bgkmap/io/atomic_file.hpp"
#include "bgkmap/io/errors.hpp"
#include "bgkmap/io/map_io.hpp"
#include "bgkmap/io/native_map.hpp"
#include "cli/commands.hpp"
#include "cli/output_names.hpp"
#include "cli/ot_values_option.hpp"
#include "cli/progress.hpp"

namespace bgkmap::cli {

void add_merge_command(CLI::App& app) {
  struct Request {
    std::string shards;
    std::vector<std::string> outputs;
    std::string ot_values = "classified";
    ProgressFlags progress;
  };
  auto req = std::make_shared<Request>();
  CLI::App* cmd = app.add_subcommand("merge", "Merge the shards of a distributed build (mpirun -np K bgkmap build) into one map");
  cmd->add_option("shards", req->shards, "The shard folder or its manifest.json")->required();
  cmd->add_option("-o,--output", req->outputs, "Output map (repeat -o for several); format from the extension: .bgk, .ot, .bt, or an export (bgkmap export): .pgm, .ply, .pcd")
      ->required()
      ->check(map_output_extension());
  add_ot_values_option(*cmd, req->ot_values);
  add_progress_flags(*cmd, req->progress, "No progress bar");
  cmd->callback([req] {
    namespace fs = std::filesystem;
    std::error_code ec;
    if (!fs::exists(req->shards, ec)) throw InputError(req->shards, "no such shard folder or manifest");
    const fs::path folder = fs::is_directory(req->shards, ec) ? fs::path(req->shards) : fs::path(req->shards).parent_path();
    const fs::path shard_folder = fs::weakly_canonical(folder.empty() ? "." : folder, ec);
    for (const std::string& out : req->outputs) {
      check_map_output(out);
      // A map written there could replace a shard or the manifest the merge reads.
      const fs::path out_folder = fs::weakly_canonical(fs::absolute(out).parent_path(), ec);
      if (out_folder == shard_folder)
        throw std::invalid_argument("-o " + out + ": inside the shard folder " + (folder.empty() ? std::string(".") : folder.string()) +
                                    ", which the merge reads; write the merged map elsewhere");
    }
    ShardManifest manifest;
    ProgressBar progress(req->progress);
    const BgkMap merged = merge_shards(req->shards, &manifest, progress.callback());
    progress.finish();
    OutputBatch outputs;
    for (const std::string& out : req->outputs) {
      if (map_format_from_path(out) == MapFormat::kNative) write_native_map(out, merged, manifest.held);
      else write_map(out, merged, "bgkl", tree_values_from_string(req->ot_values));
    }
    outputs.commit();
  });
}

}  // namespace bgkmap::cli
