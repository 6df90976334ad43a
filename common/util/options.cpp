#include "common/util/options.h"

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>

namespace lightfarm {

OptionMap OptionMap::Parse(const std::vector<std::string>& entries) {
  std::map<std::string, std::string> values;
  for (const std::string& e : entries) {
    size_t eq = e.find('=');
    if (eq == std::string::npos || eq == 0)
      throw OptionError("--param expects KEY=VALUE, got \"" + e + "\"");
    std::string key = e.substr(0, eq);
    if (!values.emplace(key, e.substr(eq + 1)).second)
      throw OptionError("--param " + key + " given twice");
  }
  return OptionMap(std::move(values));
}

void OptionMap::AddMissing(const std::vector<std::string>& entries) {
  for (const auto& [key, value] : Parse(entries).values_) values_.emplace(key, value);
}

const std::string* OptionMap::Lookup(const std::string& key) const {
  auto it = values_.find(key);
  if (it == values_.end()) return nullptr;
  used_.insert(key);
  return &it->second;
}

namespace {

// The shortest text that reads back as `v`.
std::string Exact(double v) {
  char buf[32];
  for (int precision = 6; precision <= 17; ++precision) {
    std::snprintf(buf, sizeof buf, "%.*g", precision, v);
    if (std::strtod(buf, nullptr) == v) break;
  }
  return buf;
}

}  // namespace

double OptionMap::GetDouble(const std::string& key, double def, double lo, double hi) const {
  const std::string* v = Lookup(key);
  if (!v) {
    defaults_.emplace(key, Exact(def));
    return def;
  }
  errno = 0;
  char* end = nullptr;
  double d = std::strtod(v->c_str(), &end);
  if (v->empty() || *end != '\0' || errno == ERANGE || !std::isfinite(d))
    throw OptionError("--param " + key + "=" + *v + ": not a number");
  if (d < lo || d > hi)
    throw OptionError("--param " + key + "=" + *v + ": must be in [" + std::to_string(lo) + ", " +
                      std::to_string(hi) + "]");
  return d;
}

long long OptionMap::GetInt(const std::string& key, long long def, long long lo, long long hi) const {
  const std::string* v = Lookup(key);
  if (!v) {
    defaults_.emplace(key, std::to_string(def));
    return def;
  }
  errno = 0;
  char* end = nullptr;
  long long i = std::strtoll(v->c_str(), &end, 10);
  if (v->empty() || *end != '\0' || errno == ERANGE)
    throw OptionError("--param " + key + "=" + *v + ": not an integer");
  if (i < lo || i > hi)
    throw OptionError("--param " + key + "=" + *v + ": must be in [" + std::to_string(lo) + ", " +
                      std::to_string(hi) + "]");
  return i;
}

std::optional<double> OptionMap::GetOptionalDouble(const std::string& key, double lo, double hi,
                                                   const std::string& default_text) const {
  if (!Has(key)) {
    defaults_.emplace(key, default_text);
    return std::nullopt;
  }
  return GetDouble(key, 0, lo, hi);
}

std::optional<long long> OptionMap::GetOptionalInt(const std::string& key, long long lo, long long hi,
                                                   const std::string& default_text) const {
  if (!Has(key)) {
    defaults_.emplace(key, default_text);
    return std::nullopt;
  }
  return GetInt(key, 0, lo, hi);
}

bool OptionMap::GetBool(const std::string& key, bool def) const {
  const std::string* v = Lookup(key);
  if (!v) {
    defaults_.emplace(key, def ? "true" : "false");
    return def;
  }
  if (*v == "true" || *v == "1" || *v == "on") return true;
  if (*v == "false" || *v == "0" || *v == "off") return false;
  throw OptionError("--param " + key + "=" + *v + ": expected true or false");
}

std::string OptionMap::GetString(const std::string& key, const std::string& def) const {
  const std::string* v = Lookup(key);
  if (!v) {
    defaults_.emplace(key, def);
    return def;
  }
  return *v;
}

void OptionMap::RejectUnused() const {
  for (const auto& [key, value] : values_)
    if (!used_.count(key)) throw OptionError("unknown --param \"" + key + "\"");
}

}  // namespace lightfarm
