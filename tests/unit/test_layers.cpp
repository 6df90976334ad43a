// The layout is the architecture (DESIGN.md, "Dependencies"), and the build says what the
// layers are: CMake writes every lightfarm target's sources and links to layers.txt
// (CMakeLists.txt, last section), and these tests check every #include of every source file
// against it. A file may include a header of its own target or of a target its target links
// (directly or through others); a shortcut across layers fails here at the next test run
// instead of in review, and so does a link that would drag a layer where it does not belong.
//   lightfarm_common (the renderer, common/; no networking)  <-  lightfarm_farm_core (common/farm/:
//   the wire's rules, gRPC, protobuf, OpenSSL)  <-  lightfarm_coordinator, lightfarm_worker
//   (never each other)  <-  lightfarm (cli/; embedded mode links both)
//   lightfarm_common  <-  lightfarm_evaluation (common/evaluation/: bench, reports, cost model)
//   <-  lightfarm (the CLI) and the tests only
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

namespace lightfarm {
namespace test_layers {

namespace fs = std::filesystem;

bool StartsWith(const std::string& s, const std::string& prefix) { return s.rfind(prefix, 0) == 0; }

// The folders whose files belong to the product's targets (tests/ builds test executables).
const std::vector<std::string> kFolders = {"common", "coordinator", "worker", "cli", "bench"};

struct Layers {
  std::map<std::string, std::set<std::string>> links;  // target -> direct link items
  std::map<std::string, std::string> owner;            // source file (relative to the root) -> target
  std::set<std::string> targets;

  // Everything `target` links, directly or through lightfarm targets, itself included.
  std::set<std::string> Closure(const std::string& target) const {
    std::set<std::string> seen = {target};
    std::vector<std::string> pending = {target};
    while (!pending.empty()) {
      const std::string t = pending.back();
      pending.pop_back();
      const auto it = links.find(t);
      if (it == links.end()) continue;
      for (const std::string& l : it->second)
        if (seen.insert(l).second) pending.push_back(l);
    }
    return seen;
  }
};

Layers ReadLayers() {
  Layers layers;
  std::ifstream in(LIGHTFARM_LAYERS_FILE);
  EXPECT_TRUE(in) << "cannot read " << LIGHTFARM_LAYERS_FILE;
  const fs::path root = fs::weakly_canonical(LIGHTFARM_SOURCE_DIR);
  std::string line;
  while (std::getline(in, line)) {
    std::vector<std::string> f;
    std::stringstream ss(line);
    for (std::string cell; std::getline(ss, cell, '\t');) f.push_back(cell);
    if (f.size() == 2 && f[0] == "target") layers.targets.insert(f[1]);
    if (f.size() == 3 && f[0] == "link") layers.links[f[1]].insert(f[2]);
    if (f.size() == 3 && f[0] == "source") {
      const fs::path rel = fs::weakly_canonical(f[2]).lexically_relative(root);
      if (!rel.empty() && !StartsWith(rel.generic_string(), "..")) {
        const auto [it, inserted] = layers.owner.emplace(rel.generic_string(), f[1]);
        EXPECT_TRUE(inserted) << rel.generic_string() << " is built into " << it->second << " and " << f[1];
      }
    }
  }
  return layers;
}

struct Include {
  std::string file;    // relative to the source root
  std::string target;  // what the directive names, quotes or brackets removed
  int line;
};

std::string Where(const Include& inc) { return inc.file + ":" + std::to_string(inc.line) + " includes " + inc.target; }

std::vector<std::string> SourceFiles() {
  const fs::path root = LIGHTFARM_SOURCE_DIR;
  std::vector<std::string> out;
  for (const std::string& folder : kFolders)
    for (const auto& entry : fs::recursive_directory_iterator(root / folder)) {
      const std::string ext = entry.path().extension().string();
      if (entry.is_regular_file() && (ext == ".h" || ext == ".cpp"))
        out.push_back(fs::relative(entry.path(), root).generic_string());
    }
  return out;
}

std::vector<Include> AllIncludes() {
  const std::regex directive(R"(^\s*#\s*include\s*[<"]([^>"]+)[>"])");
  std::vector<Include> out;
  for (const std::string& file : SourceFiles()) {
    std::ifstream in(fs::path(LIGHTFARM_SOURCE_DIR) / file);
    std::string text;
    int line = 0;
    while (std::getline(in, text)) {
      ++line;
      std::smatch m;
      if (std::regex_search(text, m, directive)) out.push_back({file, m[1].str(), line});
    }
  }
  return out;
}

// The target a file of the source tree belongs to: a .cpp's is the build's; a header's is its
// .cpp's, or (header-only) the target most of its folder's sources are built into. "" if none.
std::string OwnerOf(const Layers& layers, const std::string& file) {
  if (const auto it = layers.owner.find(file); it != layers.owner.end()) return it->second;
  const fs::path p(file);
  if (p.extension() == ".h") {
    const std::string cpp = (p.parent_path() / p.stem()).generic_string() + ".cpp";
    if (const auto it = layers.owner.find(cpp); it != layers.owner.end()) return it->second;
  }
  // Header-only: the folder's target, or (a folder without sources, like coordinator/web/,
  // whose sources are generated) the nearest enclosing folder's.
  for (fs::path folder = p.parent_path(); !folder.empty(); folder = folder.parent_path()) {
    std::map<std::string, int> votes;
    for (const auto& [source, target] : layers.owner)
      if (fs::path(source).parent_path() == folder) ++votes[target];
    std::string best;
    for (const auto& [target, n] : votes)
      if (best.empty() || n > votes[best]) best = target;
    if (!best.empty()) return best;
  }
  return "";
}

TEST(Layers, TheBuildsTargetsAreReadAndEverySourceIsBuilt) {
  // Guards the tests below against passing on an empty or stale layers.txt.
  const Layers layers = ReadLayers();
  for (const char* t : {"lightfarm_common", "lightfarm_farm_core", "lightfarm_evaluation",
                        "lightfarm_coordinator", "lightfarm_worker", "lightfarm"})
    EXPECT_TRUE(layers.targets.count(t)) << t;
  EXPECT_EQ(layers.owner.at("common/render/render_job.cpp"), "lightfarm_common");
  EXPECT_EQ(layers.owner.at("common/farm/rpc.cpp"), "lightfarm_farm_core");
  EXPECT_TRUE(layers.Closure("lightfarm-worker").count("lightfarm_common"));
  EXPECT_GT(AllIncludes().size(), 1000u);
  // A .cpp no target builds would be a file nobody compiles, and one these tests cannot place.
  for (const std::string& file : SourceFiles()) {
    if (fs::path(file).extension() == ".cpp") {
      EXPECT_TRUE(layers.owner.count(file)) << file << " is in no target";
    }
  }
}

TEST(Layers, EveryIncludePointsAlongALink) {
  const Layers layers = ReadLayers();
  const fs::path root = LIGHTFARM_SOURCE_DIR;
  std::map<std::string, std::set<std::string>> closures;
  size_t checked = 0;
  for (const Include& inc : AllIncludes()) {
    const std::string from = OwnerOf(layers, inc.file);
    std::string to;
    if (StartsWith(inc.target, "lightfarm/v1/")) {
      to = "lightfarm_proto";  // generated from proto/
    } else if (fs::is_regular_file(root / inc.target)) {
      to = OwnerOf(layers, inc.target);
    } else {
      continue;  // a system or third-party header
    }
    ASSERT_FALSE(from.empty()) << inc.file;
    ASSERT_FALSE(to.empty()) << inc.target;
    // The image module's interface: a header of declarations only (no definitions to link),
    // the contract between the renderer and the plugin it loads.
    if (from == "lightfarm_imageio" && inc.target == "common/image/image_io_backend.h") continue;
    if (!closures.count(from)) closures[from] = layers.Closure(from);
    EXPECT_TRUE(closures[from].count(to)) << Where(inc) << ": " << from << " does not link " << to;
    ++checked;
  }
  EXPECT_GT(checked, 400u);
}

TEST(Layers, OnlyTargetsThatLinkTheFarmCoreTalkGrpcProtobufOrOpenSsl) {
  // The renderer (lightfarm_common) and the evaluation tools link none of them: a gather method,
  // the scene or the render pipeline that included one would not link, or would drag gRPC into
  // every tool.
  const Layers layers = ReadLayers();
  for (const Include& inc : AllIncludes()) {
    const bool networked = StartsWith(inc.target, "grpc") || StartsWith(inc.target, "lightfarm/v1/") ||
                           StartsWith(inc.target, "google/protobuf") || StartsWith(inc.target, "openssl/");
    if (!networked) continue;
    const std::string from = OwnerOf(layers, inc.file);
    EXPECT_TRUE(layers.Closure(from).count("lightfarm_farm_core") || from == "lightfarm_farm_core")
        << Where(inc) << " in " << from;
  }
}

TEST(Layers, TheTargetsPointOneWay) {
  const Layers layers = ReadLayers();
  const auto lightfarm_targets_in = [&](const std::string& target) {
    std::set<std::string> out;
    for (const std::string& t : layers.Closure(target))
      if (t != target && layers.targets.count(t)) out.insert(t);
    return out;
  };
  // The renderer links nothing of lightfarm (the image module is loaded, not linked).
  EXPECT_EQ(lightfarm_targets_in("lightfarm_common"), std::set<std::string>{});
  EXPECT_EQ(lightfarm_targets_in("lightfarm_evaluation"), std::set<std::string>{"lightfarm_common"});
  EXPECT_EQ(lightfarm_targets_in("lightfarm_farm_core"), (std::set<std::string>{"lightfarm_common", "lightfarm_proto"}));
  EXPECT_FALSE(layers.Closure("lightfarm_coordinator").count("lightfarm_worker"));
  EXPECT_FALSE(layers.Closure("lightfarm_worker").count("lightfarm_coordinator"));
  // The evaluation tools are the CLI's: no farm process or library carries them.
  for (const std::string& t : layers.targets) {
    if (t != "lightfarm" && t != "lightfarm_evaluation") {
      EXPECT_FALSE(layers.Closure(t).count("lightfarm_evaluation")) << t << " links lightfarm_evaluation";
    }
  }
}

TEST(Layers, FoldersAreTargets) {
  // Each folder of common/ is built into one library: common/farm/ is the farm core,
  // common/evaluation/ the evaluation tools, the rest the renderer. The one exception is the
  // image module, a plugin loaded on the first image read (common/image/image_io_backend.h).
  const Layers layers = ReadLayers();
  std::map<std::string, std::set<std::string>> by_folder;
  for (const auto& [file, target] : layers.owner)
    if (StartsWith(file, "common/") && target != "lightfarm_imageio")
      by_folder[fs::path(file).parent_path().generic_string()].insert(target);
  EXPECT_GE(by_folder.size(), 10u);
  for (const auto& [folder, targets] : by_folder) {
    const std::string expected = folder == "common/farm"         ? "lightfarm_farm_core"
                                 : folder == "common/evaluation" ? "lightfarm_evaluation"
                                                                 : "lightfarm_common";
    EXPECT_EQ(targets, std::set<std::string>{expected}) << folder;
  }
}

}  // namespace test_layers
}  // namespace lightfarm
