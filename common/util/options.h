// KEY=VALUE parameters (`--param clamp=0.02`), read by whoever they configure. Each read marks
// the key used; once everyone has read, RejectUnused() makes a typo an error, not a silent no-op.
#pragma once

#include <map>
#include <set>
#include <string>
#include <vector>

#include "common/util/error.h"

namespace lightfarm {

class OptionMap {
 public:
  OptionMap() = default;
  explicit OptionMap(std::map<std::string, std::string> values) : values_(std::move(values)) {}
  // Parses "key=value"; throws OptionError on a malformed entry or a repeated key.
  static OptionMap Parse(const std::vector<std::string>& entries);

  double GetDouble(const std::string& key, double def, double lo, double hi) const;
  long long GetInt(const std::string& key, long long def, long long lo, long long hi) const;
  bool GetBool(const std::string& key, bool def) const;
  std::string GetString(const std::string& key, const std::string& def) const;
  bool Has(const std::string& key) const { return values_.count(key) != 0; }

  // Throws OptionError naming the first key nobody read.
  void RejectUnused() const;
  const std::map<std::string, std::string>& values() const { return values_; }

 private:
  const std::string* Lookup(const std::string& key) const;
  std::map<std::string, std::string> values_;
  mutable std::set<std::string> used_;
};

}  // namespace lightfarm
