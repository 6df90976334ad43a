// The layout is the architecture (DESIGN.md, "Dependencies"): these tests read every source file's
// #include lines and fail on an arrow pointing the wrong way, so a shortcut across layers is
// caught at the next test run instead of in review.
//   common/ (the renderer and its pipeline, common/render/; no networking)  <-  common/farm/ (the
//   farm core: the wire's rules, gRPC, protobuf, OpenSSL)
//   <-  coordinator/, worker/ (never each other)  <-  cli/ (embedded mode links both)
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <regex>
#include <string>
#include <vector>

namespace lightfarm {
namespace test_layers {

namespace fs = std::filesystem;

struct Include {
  std::string file;    // relative to the source root
  std::string target;  // what the directive names, quotes or brackets removed
  int line;
};

// Every #include of every C++ file under the given top-level folders.
std::vector<Include> IncludesUnder(const std::vector<std::string>& folders) {
  const fs::path root = LIGHTFARM_SOURCE_DIR;
  const std::regex directive(R"(^\s*#\s*include\s*[<"]([^>"]+)[>"])");
  std::vector<Include> out;
  for (const std::string& folder : folders) {
    for (const auto& entry : fs::recursive_directory_iterator(root / folder)) {
      const std::string ext = entry.path().extension().string();
      if (!entry.is_regular_file() || (ext != ".h" && ext != ".cpp")) continue;
      std::ifstream in(entry.path());
      std::string text;
      int line = 0;
      while (std::getline(in, text)) {
        ++line;
        std::smatch m;
        if (std::regex_search(text, m, directive))
          out.push_back({fs::relative(entry.path(), root).generic_string(), m[1].str(), line});
      }
    }
  }
  return out;
}

bool StartsWith(const std::string& s, const std::string& prefix) { return s.rfind(prefix, 0) == 0; }

// common/farm/ is the farm's shared layer, target lightfarm_farm_core (CMakeLists.txt builds it
// from the folder, and lightfarm_common from common/ without it): the folder is the target.
bool IsFarmCore(const std::string& file) { return StartsWith(file, "common/farm/"); }

std::string Where(const Include& inc) { return inc.file + ":" + std::to_string(inc.line) + " includes " + inc.target; }

TEST(Layers, TheScannerSeesTheFarmIncludes) {
  // Guards the tests below against passing on an empty scan (a moved folder, a broken regex).
  bool worker_includes_core = false;
  for (const Include& inc : IncludesUnder({"worker"}))
    worker_includes_core |= inc.file == "worker/worker.cpp" && inc.target == "common/farm/rpc.h";
  EXPECT_TRUE(worker_includes_core);
  EXPECT_GT(IncludesUnder({"common"}).size(), 500u);
}

TEST(Layers, CommonNeverIncludesTheFarmProcessesOrTheCli) {
  for (const Include& inc : IncludesUnder({"common"}))
    for (const char* upper : {"coordinator/", "worker/", "cli/"})
      EXPECT_FALSE(StartsWith(inc.target, upper)) << Where(inc);
}

TEST(Layers, CoordinatorAndWorkerNeverIncludeEachOther) {
  for (const Include& inc : IncludesUnder({"coordinator"}))
    EXPECT_FALSE(StartsWith(inc.target, "worker/") || StartsWith(inc.target, "cli/")) << Where(inc);
  for (const Include& inc : IncludesUnder({"worker"}))
    EXPECT_FALSE(StartsWith(inc.target, "coordinator/") || StartsWith(inc.target, "cli/")) << Where(inc);
}

TEST(Layers, OnlyTheFarmCoreOfCommonTalksGrpcProtobufOrOpenSsl) {
  // The renderer library (lightfarm_common) links none of them: a gather method, the scene or
  // the farm's job plan that included one would not link, or would drag gRPC into every tool.
  for (const Include& inc : IncludesUnder({"common"})) {
    const bool networked = StartsWith(inc.target, "grpc") || StartsWith(inc.target, "lightfarm/v1/") ||
                           StartsWith(inc.target, "google/protobuf") || StartsWith(inc.target, "openssl/");
    if (networked) {
      EXPECT_TRUE(IsFarmCore(inc.file)) << Where(inc);
    }
    // Nor may the renderer include the farm core's headers (it is not linked with them).
    if (!IsFarmCore(inc.file) && IsFarmCore(inc.target)) {
      ADD_FAILURE() << Where(inc) << ", a header of lightfarm_farm_core";
    }
  }
}

}  // namespace test_layers
}  // namespace lightfarm
