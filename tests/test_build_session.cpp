// The library's BuildSession: the map it writes is the Mapper's on the same scans, reading ahead
// changes nothing, bad inputs are skipped and reported, and it prints nothing itself.
#include <gtest/gtest.h>

#include <cstdint>
#include <string>
#include <vector>

#include "bgkmap/build/build_session.hpp"
#include "bgkmap/io/map_io.hpp"
#include "bgkmap/io/pcd_io.hpp"
#include "support/test_support.hpp"

namespace bgkmap {
namespace {

class BuildSessionTest : public ::testing::Test {
 protected:
  void SetUp() override {
    scans_ = testing::random_scans(7, 4, 300, 1.5f);
    for (size_t i = 0; i < scans_.size(); ++i) write_pcd(dir_ / ("s_" + std::to_string(i + 1) + ".pcd"), scans_[i]);
  }
  BuildRequest request(const std::string& output, int threads) const {
    BuildRequest req;
    req.inputs = {dir_.path().string()};
    req.outputs = {(dir_ / output).string()};
    req.params = testing::small_params();
    req.backend = testing::cpu_backend(threads);
    req.note = [this](const std::string& line) { notes_.push_back(line); };
    return req;
  }
  testing::TempDir dir_{"build_session"};
  std::vector<Scan> scans_;
  mutable std::vector<std::string> notes_;
};

TEST_F(BuildSessionTest, MapIsTheMappersOnTheSameScans) {
  ::testing::internal::CaptureStderr();
  const BuildReport report = BuildSession(request("m.bgk", 2)).run();
  EXPECT_EQ(::testing::internal::GetCapturedStderr(), "");  // the library prints nothing
  EXPECT_TRUE(notes_.empty());
  EXPECT_EQ(report.counts.scans, scans_.size());
  EXPECT_EQ(report.inputs.size(), scans_.size());

  Mapper reference(testing::small_params(), make_integrator(testing::cpu_backend(2)));
  for (const Scan& scan : testing::read_all_scans({dir_.path()})) reference.insert(scan);
  reference.finish();
  const NativeMapFile built = read_native_map_file(dir_ / "m.bgk");
  ASSERT_EQ(built.map.cells_with_evidence(), reference.map().cells_with_evidence());
  ASSERT_GT(built.map.cells_with_evidence(), 1000u);
  EXPECT_EQ(report.known_cells, reference.map().cells_with_evidence());
  uint64_t compared = 0;
  built.map.for_each_cell_with_evidence([&](const CellIndex& cell, const CellPosterior& p) {
    const Vec3d c = built.map.grid().cell_center_d(cell);
    const CellPosterior want = reference.map().query(c.x, c.y, c.z);
    EXPECT_EQ(p.alpha, want.alpha);
    EXPECT_EQ(p.beta, want.beta);
    ++compared;
  });
  EXPECT_EQ(compared, built.map.cells_with_evidence());
}

TEST_F(BuildSessionTest, ReadingAheadWritesTheSameBytes) {
  BuildSession(request("serial.bgk", 2)).run();
  const BuildReport ahead = BuildSession(request("ahead.bgk", 8)).run();  // 8 threads: one reads ahead
  EXPECT_EQ(ahead.backend_asked.threads, 8);
  EXPECT_EQ(testing::read_bytes(dir_ / "ahead.bgk"), testing::read_bytes(dir_ / "serial.bgk"));
}

TEST_F(BuildSessionTest, BadInputsAreSkippedAndReported) {
  testing::write_bytes(dir_ / "s_3.pcd", "not a pcd file\n");
  BuildRequest req = request("m.ot", 2);
  req.report = (dir_ / "report.json").string();
  req.skip_bad_inputs = true;
  ::testing::internal::CaptureStderr();
  const BuildReport report = BuildSession(req).run();
  EXPECT_EQ(::testing::internal::GetCapturedStderr(), "");
  EXPECT_EQ(report.counts.scans, scans_.size() - 1);
  ASSERT_EQ(report.skipped.size(), 1u);
  EXPECT_EQ(report.skipped[0].path, (dir_ / "s_3.pcd").string());
  ASSERT_EQ(notes_.size(), 1u);
  EXPECT_EQ(notes_[0], "skipping bad input " + report.skipped[0].error);
  const nlohmann::json json = nlohmann::json::parse(testing::read_bytes(dir_ / "report.json"));
  EXPECT_EQ(json, report_json(report));
  EXPECT_EQ(json["counts"]["inputs_skipped"], 1);
  EXPECT_EQ(json["skipped_inputs"][0]["path"], report.skipped[0].path);

  req.skip_bad_inputs = false;  // without skipping, the bad file stops the build and nothing is written
  req.outputs = {(dir_ / "stopped.ot").string()};
  req.report.clear();
  EXPECT_THROW(BuildSession(req).run(), InputError);
  EXPECT_FALSE(std::filesystem::exists(dir_ / "stopped.ot"));
}

TEST_F(BuildSessionTest, ResumeRefusesAChangedParameter) {
  BuildRequest first = request("first.bgk", 2);
  first.inputs = {(dir_ / "s_1.pcd").string(), (dir_ / "s_2.pcd").string()};
  BuildSession(first).run();
  BuildRequest resumed = request("resumed.bgk", 2);
  resumed.resume.resume = (dir_ / "first.bgk").string();
  const BuildReport report = BuildSession(resumed).run();
  EXPECT_EQ(report.scans_already_held, 2u);
  EXPECT_EQ(report.counts.scans, scans_.size() - 2);
  ASSERT_EQ(notes_.size(), 1u);
  EXPECT_EQ(notes_[0], resumed.resume.resume + " holds 2 scans of these inputs already: skipping them");
  BuildSession(request("whole.bgk", 2)).run();
  EXPECT_EQ(testing::read_bytes(dir_ / "resumed.bgk"), testing::read_bytes(dir_ / "whole.bgk"));

  resumed.outputs = {(dir_ / "other.bgk").string()};
  resumed.resume.params = [](const BuildParams& stored) {
    BuildParams wanted = stored;
    wanted.kernel.ell_m *= 2;
    return resumed_params(stored, wanted);
  };
  try {
    BuildSession(resumed).run();
    FAIL() << "a changed ell was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()).rfind("cannot change 'ell' when resuming a map", 0), 0u) << e.what();
  }
}

}  // namespace
}  // namespace bgkmap
