// KEY=VALUE parameters (`--param clamp=0.02`), read by whoever they configure. Each read marks
// the key used; once everyone has read, RejectUnused() makes a typo an error, not a silent no-op.
// A read of an absent key records the default it fell back to, so the one place a default is
// written (the reader's call) is also where a caller can learn it (defaults_read).
#pragma once

#include <map>
#include <optional>
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
  // A key whose default the caller derives (from the scene, the light count, another key):
  // nullopt when absent, and `default_text` says what it falls back to (defaults_read).
  std::optional<double> GetOptionalDouble(const std::string& key, double lo, double hi,
                                          const std::string& default_text) const;
  std::optional<long long> GetOptionalInt(const std::string& key, long long lo, long long hi,
                                          const std::string& default_text) const;
  bool Has(const std::string& key) const { return values_.count(key) != 0; }
  // Adds "key=value" entries whose key is not set (a value the user gave wins); throws
  // OptionError on a malformed entry.
  void AddMissing(const std::vector<std::string>& entries);

  // Throws OptionError naming the first key nobody read.
  void RejectUnused() const;
  const std::map<std::string, std::string>& values() const { return values_; }
  // The defaults of the keys read while absent, as text (numbers printed exactly).
  const std::map<std::string, std::string>& defaults_read() const { return defaults_; }

 private:
  const std::string* Lookup(const std::string& key) const;
  std::map<std::string, std::string> values_;
  mutable std::set<std::string> used_;
  mutable std::map<std::string, std::string> defaults_;
};

}  // namespace lightfarm
