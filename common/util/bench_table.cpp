#include "common/util/bench_table.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <sstream>
#include <tuple>
#include <stdexcept>

namespace lightfarm {

namespace {

const char* kColumns[] = {"scene", "lights", "width", "height", "spp", "seed", "method",
                          "setting", "repeat", "time_total_s", "time_plan_s", "time_gather_s",
                          "shadow_rays", "shadow_rays_per_pixel", "elements",
                          "fraction_evaluated", "rel_l2", "rel_l1", "peak_rss_mb", "reference",
                          "estimated", "phases", "image", "truth_rel_l1", "truth_rel_l2",
                          "fireflies"};

// Settings hold commas ("rows=50,columns=100"); the CSV keeps them space-separated so that no
// field needs quoting and plain tools (cut, gnuplot, awk) read the file.
std::string ToField(std::string s) {
  for (char& c : s)
    if (c == ',' || c == '\n') c = ' ';
  return s;
}
std::string FromField(std::string s) {
  for (char& c : s)
    if (c == ' ') c = ',';
  return s;
}

std::string Num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

// The median of the finite values; NaN when there are none.
double Median(std::vector<double> v) {
  v.erase(std::remove_if(v.begin(), v.end(), [](double x) { return !std::isfinite(x); }), v.end());
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

}  // namespace

std::string BenchCsvHeader() {
  std::string h;
  for (const char* c : kColumns) h += (h.empty() ? "" : ",") + std::string(c);
  return h;
}

std::string ToCsvLine(const BenchRow& r) {
  std::vector<std::string> f = {ToField(r.scene), std::to_string(r.lights), std::to_string(r.width),
                                std::to_string(r.height), std::to_string(r.spp),
                                std::to_string(r.seed), r.method, ToField(r.setting),
                                std::to_string(r.repeat), Num(r.time_total_s), Num(r.time_plan_s),
                                Num(r.time_gather_s), Num(r.shadow_rays),
                                Num(r.shadow_rays_per_pixel), Num(r.elements),
                                Num(r.fraction_evaluated), Num(r.rel_l2), Num(r.rel_l1),
                                Num(r.peak_rss_mb), r.reference, r.estimated ? "1" : "0",
                                ToField(r.phases), ToField(r.image), Num(r.truth_rel_l1),
                                Num(r.truth_rel_l2), Num(r.fireflies)};
  std::string line;
  for (const std::string& s : f) line += (line.empty() ? "" : ",") + s;
  return line;
}

std::vector<BenchRow> ReadBenchCsv(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot read " + path);
  return ParseBenchCsv(in, path);
}

std::vector<BenchRow> ParseBenchCsv(std::istream& in, const std::string& path) {
  std::string line;
  if (!std::getline(in, line)) throw std::runtime_error(path + ": empty, not a lightfarm bench results.csv");
  std::vector<std::string> header;
  {
    std::stringstream ss(line);
    std::string cell;
    while (std::getline(ss, cell, ',')) header.push_back(cell);
  }
  // Columns by name: every column up to `image` is required (the first format), later ones are
  // optional so that cost models written before them still read.
  std::map<std::string, size_t> column;
  for (size_t i = 0; i < header.size(); ++i) column[header[i]] = i;
  for (const char* c : kColumns) {
    if (column.count(c)) continue;
    if (std::string(c) == "truth_rel_l1" || std::string(c) == "truth_rel_l2" || std::string(c) == "fireflies")
      continue;
    throw std::runtime_error(path + ": not a lightfarm bench results.csv (no column " + c + ")");
  }
  std::vector<BenchRow> rows;
  while (std::getline(in, line)) {
    if (line.empty()) continue;
    std::vector<std::string> f;
    std::stringstream ss(line);
    std::string cell;
    while (std::getline(ss, cell, ',')) f.push_back(cell);
    if (!line.empty() && line.back() == ',') f.push_back("");
    if (f.size() != header.size())
      throw std::runtime_error(path + ": row with " + std::to_string(f.size()) + " fields, the header has " +
                               std::to_string(header.size()));
    auto get = [&](const char* name) -> const std::string& { return f[column.at(name)]; };
    auto num = [&](const char* name) {
      const auto it = column.find(name);
      if (it == column.end() || f[it->second] == "nan" || f[it->second] == "-nan") return std::nan("");
      return std::stod(f[it->second]);
    };
    BenchRow r;
    r.scene = get("scene");
    r.lights = std::stoull(get("lights"));
    r.width = std::stoi(get("width"));
    r.height = std::stoi(get("height"));
    r.spp = std::stoi(get("spp"));
    r.seed = std::stoull(get("seed"));
    r.method = get("method");
    r.setting = FromField(get("setting"));
    r.repeat = std::stoi(get("repeat"));
    r.time_total_s = num("time_total_s");
    r.time_plan_s = num("time_plan_s");
    r.time_gather_s = num("time_gather_s");
    r.shadow_rays = num("shadow_rays");
    r.shadow_rays_per_pixel = num("shadow_rays_per_pixel");
    r.elements = num("elements");
    r.fraction_evaluated = num("fraction_evaluated");
    r.rel_l2 = num("rel_l2");
    r.rel_l1 = num("rel_l1");
    r.peak_rss_mb = num("peak_rss_mb");
    r.reference = get("reference");
    r.estimated = get("estimated") == "1";
    r.phases = get("phases");
    r.image = get("image");
    r.truth_rel_l1 = num("truth_rel_l1");
    r.truth_rel_l2 = num("truth_rel_l2");
    r.fireflies = num("fireflies");
    rows.push_back(std::move(r));
  }
  return rows;
}

std::vector<SettingSummary> Summarize(const std::vector<BenchRow>& rows) {
  std::vector<SettingSummary> out;
  std::map<std::tuple<size_t, std::string, std::string>, std::vector<const BenchRow*>> groups;
  for (const BenchRow& r : rows) {
    auto key = std::make_tuple(r.lights, r.method, r.setting);
    if (!groups.count(key)) {
      SettingSummary s;
      s.lights = r.lights;
      s.method = r.method;
      s.setting = r.setting;
      out.push_back(s);
    }
    groups[key].push_back(&r);
  }
  for (SettingSummary& s : out) {
    const auto& g = groups[std::make_tuple(s.lights, s.method, s.setting)];
    auto med = [&](double BenchRow::*field) {
      std::vector<double> v;
      for (const BenchRow* r : g) v.push_back(r->*field);
      return Median(v);
    };
    s.runs = int(g.size());
    s.time_s = med(&BenchRow::time_total_s);
    s.rel_l2 = med(&BenchRow::rel_l2);
    s.rel_l1 = med(&BenchRow::rel_l1);
    s.shadow_rays = med(&BenchRow::shadow_rays);
    s.shadow_rays_per_pixel = med(&BenchRow::shadow_rays_per_pixel);
    s.elements = med(&BenchRow::elements);
    s.peak_rss_mb = med(&BenchRow::peak_rss_mb);
    s.truth_rel_l1 = med(&BenchRow::truth_rel_l1);
    s.truth_rel_l2 = med(&BenchRow::truth_rel_l2);
    s.fireflies = med(&BenchRow::fireflies);
    s.estimated = g.front()->estimated;
    for (const BenchRow* r : g)
      if (!r->image.empty()) s.image = r->image;
  }
  return out;
}

std::vector<std::string> SplitParams(const std::string& label) {
  std::vector<std::string> out;
  std::stringstream ss(label);
  std::string item;
  while (std::getline(ss, item, ','))
    if (!item.empty()) out.push_back(item);
  return out;
}

}  // namespace lightfarm
