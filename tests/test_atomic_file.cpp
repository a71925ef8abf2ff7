// Outputs (io/atomic_file): checked up front with the system's reason, devices and FIFOs written
// through rather than replaced, links kept, stale temporaries of killed runs removed, and several
// outputs committed together or not at all.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fstream>
#include <iterator>
#include <set>
#include <stdexcept>
#include <string>
#include <thread>

#include "bgkmap/io/atomic_file.hpp"
#include "support/test_support.hpp"

namespace bgkmap {
namespace {

namespace fs = std::filesystem;

class AtomicFile : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = testing::make_temp_dir("atomic"); }
  void TearDown() override { fs::remove_all(dir_); }
  std::set<std::string> entries() const {
    std::set<std::string> names;
    for (const auto& e : fs::directory_iterator(dir_)) names.insert(e.path().filename().string());
    return names;
  }
  static void put(const fs::path& file, const std::string& text) {
    write_file_atomically(file, [&](std::ostream& out) { out << text; });
  }
  // The message check_output_path throws for `target` ("" when it accepts it).
  static std::string refusal(const fs::path& target) {
    try {
      check_output_path(target);
    } catch (const std::runtime_error& e) {
      return e.what();
    }
    return "";
  }
  fs::path dir_;
};

// A process id that no process has now: a child that has exited and been reaped.
pid_t dead_pid() {
  const pid_t child = fork();
  if (child == 0) _exit(0);
  waitpid(child, nullptr, 0);
  return child;
}

TEST_F(AtomicFile, OutputPathsAreCheckedWithTheSystemsReason) {
  EXPECT_EQ(refusal(dir_ / "m.bgk"), "");
  EXPECT_EQ(refusal(dir_ / "missing" / "m.bgk"),
            (dir_ / "missing" / "m.bgk").string() + ": cannot write into folder " + (dir_ / "missing").string() +
                " (No such file or directory)");
  put(dir_ / "file", "x");
  EXPECT_EQ(refusal(dir_ / "file" / "m.bgk"),
            (dir_ / "file" / "m.bgk").string() + ": cannot write (Not a directory)");
  fs::create_directories(dir_ / "folder.bgk");
  EXPECT_EQ(refusal(dir_ / "folder.bgk"), (dir_ / "folder.bgk").string() + ": is a folder, not a file");
  EXPECT_EQ(entries(), (std::set<std::string>{"file", "folder.bgk"}));  // checking writes nothing

  // An output folder to be created: its nearest existing parent must be a writable folder.
  EXPECT_NO_THROW(check_output_folder(dir_ / "new" / "deeper"));
  EXPECT_THROW(check_output_folder(dir_ / "file" / "sim"), std::runtime_error);
  if (geteuid() != 0) {  // root writes into any folder whatever its mode
    fs::create_directories(dir_ / "locked");
    fs::permissions(dir_ / "locked", fs::perms::owner_read | fs::perms::owner_exec);
    EXPECT_NE(refusal(dir_ / "locked" / "m.bgk").find("(Permission denied)"), std::string::npos);
    fs::permissions(dir_ / "locked", fs::perms::owner_all);
  }
}

TEST_F(AtomicFile, AFifoIsWrittenThroughNotReplaced) {
  const fs::path fifo = dir_ / "report.json";
  ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
  std::string received;
  std::thread reader([&] {
    std::ifstream in(fifo, std::ios::binary);
    received.assign(std::istreambuf_iterator<char>(in), {});
  });
  EXPECT_EQ(refusal(fifo), "");
  put(fifo, "{\"through\": true}\n");
  reader.join();
  EXPECT_EQ(received, "{\"through\": true}\n");
  EXPECT_TRUE(fs::is_fifo(fifo));
  EXPECT_EQ(entries(), std::set<std::string>{"report.json"});  // no temporary beside it
}

TEST_F(AtomicFile, ADeviceBehindALinkIsWrittenThroughAndALinkToAFileIsKept) {
  // A link to /dev/null: were the device not recognised, only this link would be replaced.
  const fs::path device = dir_ / "null.bgk";
  fs::create_symlink("/dev/null", device);
  put(device, "discarded");
  EXPECT_TRUE(fs::is_symlink(device));
  EXPECT_TRUE(fs::is_character_file("/dev/null"));

  put(dir_ / "real.json", "old");
  fs::create_symlink("real.json", dir_ / "link.json");
  put(dir_ / "link.json", "new");
  EXPECT_TRUE(fs::is_symlink(dir_ / "link.json"));
  EXPECT_EQ(testing::read_bytes(dir_ / "real.json"), "new");
  EXPECT_EQ(entries(), (std::set<std::string>{"link.json", "null.bgk", "real.json"}));
}

TEST_F(AtomicFile, StaleTemporariesOfDeadProcessesAreRemovedOthersKept) {
  const fs::path target = dir_ / "m.ot";
  const std::string dead = "m.ot.tmp-" + std::to_string(dead_pid());
  const std::string live = "m.ot.tmp-" + std::to_string(getppid());  // a running process's
  for (const std::string& name : {dead, live, std::string("m.ot.tmp-notapid"), std::string("other.ot.tmp-1")})
    put(dir_ / name, "partial");
  check_output_path(target);
  EXPECT_EQ(entries(), (std::set<std::string>{live, "m.ot.tmp-notapid", "other.ot.tmp-1"}));
  put(dir_ / dead, "partial");
  EXPECT_EQ(remove_stale_temporaries(target), 1);
  EXPECT_EQ(remove_stale_temporaries(target), 0);
}

TEST_F(AtomicFile, ABatchCommitsEveryOutputTogether) {
  put(dir_ / "m.bgk", "old map");
  put(dir_ / "m.ot", "old tree");
  {
    OutputBatch batch;
    put(dir_ / "m.bgk", "new map");
    put(dir_ / "m.ot", "new tree");
    put(dir_ / "r.json", "report");
    // Nothing is in place until every one is complete.
    EXPECT_EQ(testing::read_bytes(dir_ / "m.bgk"), "old map");
    EXPECT_EQ(testing::read_bytes(dir_ / "m.ot"), "old tree");
    EXPECT_FALSE(fs::exists(dir_ / "r.json"));
    batch.commit();
  }
  EXPECT_EQ(testing::read_bytes(dir_ / "m.bgk"), "new map");
  EXPECT_EQ(testing::read_bytes(dir_ / "m.ot"), "new tree");
  EXPECT_EQ(testing::read_bytes(dir_ / "r.json"), "report");
  EXPECT_EQ(entries(), (std::set<std::string>{"m.bgk", "m.ot", "r.json"}));
  put(dir_ / "m.ot", "after the batch");  // no batch: in place at once
  EXPECT_EQ(testing::read_bytes(dir_ / "m.ot"), "after the batch");
}

TEST_F(AtomicFile, AFailureInABatchLeavesEveryOldOutput) {
  put(dir_ / "m.bgk", "old map");
  put(dir_ / "m.ot", "old tree");
  try {
    OutputBatch batch;
    put(dir_ / "m.bgk", "new map");
    write_file_atomically(dir_ / "m.ot", [](std::ostream&) { throw std::runtime_error("disk full"); });
    batch.commit();
    ADD_FAILURE() << "the failing write did not throw";
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()), "disk full");
  }
  EXPECT_EQ(testing::read_bytes(dir_ / "m.bgk"), "old map");
  EXPECT_EQ(testing::read_bytes(dir_ / "m.ot"), "old tree");
  EXPECT_EQ(entries(), (std::set<std::string>{"m.bgk", "m.ot"}));
}

}  // namespace
}  // namespace bgkmap
