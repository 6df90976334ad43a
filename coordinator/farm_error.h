// What the coordinator's calls throw for a request it refuses or cannot serve; the gRPC and HTTP
// services turn the code into a status (services.cpp, dashboard.cpp).
#pragma once

#include <stdexcept>
#include <string>

namespace lightfarm {

class FarmError : public std::runtime_error {
 public:
  enum class Code { kInvalidArgument, kNotFound, kResourceExhausted, kFailedPrecondition, kUnavailable, kDataLoss };
  FarmError(Code code, const std::string& message) : std::runtime_error(message), code_(code) {}
  Code code() const { return code_; }

 private:
  Code code_;
};

}  // namespace lightfarm
