// `lightfarm compare REFERENCE IMAGE [--resize] [--heatmap FILE.png] [--json]`: the error of an
// image against a reference render (DESIGN.md, Contracts).
#include <cctype>
#include <cstdio>
#include <iostream>
#include <limits>
#include <memory>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>

#include "cli/commands.h"
#include "common/image/image_io.h"
#include "common/image/metrics.h"
#include "common/util/error.h"

namespace lightfarm::cli {
namespace {

struct CompareOptions {
  std::string reference;
  std::string image;
  bool resize = false;
  std::string heatmap;
  float heatmap_max = kDefaultHeatmapMaxError;
  bool json = false;
  float exclude_above = std::numeric_limits<float>::infinity();
};

std::string SizeString(const Image& image) {
  return std::to_string(image.width) + "x" + std::to_string(image.height);
}

bool EndsWithPng(const std::string& path) {
  if (path.size() < 4) return false;
  std::string ext = path.substr(path.size() - 4);
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext == ".png";
}

void RunCompare(const CompareOptions& options) {
  if (!options.heatmap.empty() && !EndsWithPng(options.heatmap)) {
    throw OptionError("--heatmap writes a PNG; give a .png file name, not \"" + options.heatmap +
                      "\"");
  }
  if (!(options.heatmap_max > 0.f)) {
    throw OptionError("--heatmap-max must be positive, got " + std::to_string(options.heatmap_max));
  }

  // Read both images; bring the reference to the image's resolution if asked to.
  Image reference = ReadImage(options.reference);
  const Image image = ReadImage(options.image);
  if (!reference.SameSize(image)) {
    if (!options.resize) {
      throw std::runtime_error("image sizes differ: " + SizeString(reference) + " vs " +
                               SizeString(image) + " (use --resize)");
    }
    reference = ResizeImage(reference, image.width, image.height);
  }

  if (!(options.exclude_above > 0.f))
    throw OptionError("--exclude-above must be positive, got " + std::to_string(options.exclude_above));
  const ErrorMetrics metrics = CompareImages(reference, image, options.exclude_above);
  if (!options.heatmap.empty()) {
    WritePNG(options.heatmap, ErrorHeatmap(reference, image, options.heatmap_max));
  }

  if (options.json) {
    nlohmann::ordered_json out;
    out["rel_l2"] = metrics.rel_l2;
    out["rel_l1"] = metrics.rel_l1;
    out["rmse"] = metrics.rmse;
    out["excluded_pixels"] = metrics.excluded_pixels;
    out["excluded_bright"] = metrics.excluded_bright;
    out["speck_share"] = metrics.speck_share;
    out["dark_specks"] = metrics.dark_specks;
    out["bright_specks"] = metrics.bright_specks;
    out["reference"] = options.reference;
    out["image"] = options.image;
    out["width"] = image.width;
    out["height"] = image.height;
    std::cout << out.dump() << std::endl;
  } else {
    char line[200];
    std::snprintf(line, sizeof line, "rel_l2=%.6g  rel_l1=%.6g  rmse=%.6g  specks=%.4g%%", metrics.rel_l2,
                  metrics.rel_l1, metrics.rmse, 100 * metrics.speck_share);
    std::cout << line;
    if (metrics.excluded_pixels > 0)
      std::cout << "  excluded=" << metrics.excluded_pixels << " (non-finite reference pixels)";
    if (metrics.excluded_bright > 0)
      std::cout << "  excluded_bright=" << metrics.excluded_bright << " (reference pixels above --exclude-above)";
    std::cout << std::endl;
  }
}

}  // namespace

void AddCompareCommand(CLI::App& app) {
  auto options = std::make_shared<CompareOptions>();
  CLI::App* cmd = app.add_subcommand(
      "compare",
      "Error of IMAGE against REFERENCE: relative L2 (MRCS), relative L1 (Huo 2016), RMSE");
  cmd->add_option("REFERENCE", options->reference,
                  "Reference image (EXR, or anything OpenImageIO reads)")
      ->required();
  cmd->add_option("IMAGE", options->image, "Image to evaluate")->required();
  cmd->add_flag("--resize", options->resize,
                "Resample the reference to the image's resolution when they differ "
                "(area average when shrinking)");
  cmd->add_option("--heatmap", options->heatmap,
                  "Write a PNG of per-pixel error |ref - img| (luminance), relative to the "
                  "reference's mean luminance");
  cmd->add_option("--heatmap-max", options->heatmap_max,
                  "Relative error drawn in the heatmap's brightest colour")
      ->capture_default_str();
  cmd->add_option("--exclude-above", options->exclude_above,
                  "Leave out reference pixels with a channel above this (an emitter's own pixels, "
                  "which a few samples hit or miss)");
  cmd->add_flag("--json", options->json,
                "Print {\"rel_l2\", \"rel_l1\", \"rmse\", \"speck_share\", \"reference\", \"image\", "
                "\"width\", \"height\"} as JSON (speck_share: lit reference pixels below 0.3x the smallest "
                "or above 3x the largest reference value around them)");
  cmd->callback([options] { RunCompare(*options); });
}

}  // namespace lightfarm::cli
