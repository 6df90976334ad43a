// Files replaced atomically (common/util/file.h): the target is the old file or the new one,
// never half of one, and a failed write leaves neither a changed target nor a temporary file.
#include <gtest/gtest.h>

#include <filesystem>
#include <stdexcept>
#include <string>

#include "common/util/file.h"
#include "tests/common/test_util.h"

namespace lightfarm {
namespace test_file {

namespace fs = std::filesystem;
using testing::TempDir;

size_t EntriesIn(const std::string& dir) {
  size_t n = 0;
  for ([[maybe_unused]] const fs::directory_entry& e : fs::directory_iterator(dir)) ++n;
  return n;
}

TEST(AtomicFile, WriteReplacesTheWholeFileAndLeavesNothingBeside) {
  TempDir dir;
  const std::string target = dir.Write("stats.json", "old contents, longer than the new ones");
  WriteFileAtomically(target, "new");
  EXPECT_EQ(ReadFile(target), "new");
  EXPECT_EQ(EntriesIn(dir.Path("")), 1u);
}

TEST(AtomicFile, AFailedWriteLeavesTheTargetUntouchedAndRemovesTheTemporaryFile) {
  TempDir dir;
  const std::string target = dir.Write("image.exr", "the old image");
  try {
    ReplaceFileAtomically(target, [](const fs::path& temporary) {
      WriteFileAtomically(temporary, "half of");  // the temporary exists when the writer fails
      throw std::runtime_error("disk full");
    });
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()), "cannot write \"" + target + "\": disk full");
  }
  EXPECT_EQ(ReadFile(target), "the old image");
  EXPECT_EQ(EntriesIn(dir.Path("")), 1u);
}

TEST(AtomicFile, AnUnwritableDirectoryIsAnErrorNamingTheTarget) {
  TempDir dir;
  const std::string target = dir.Path("missing/dir/out.json");
  try {
    WriteFileAtomically(target, "x");
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("cannot write \"" + target + "\""), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(dir.Path("missing")));
}

}  // namespace test_file
}  // namespace lightfarm
