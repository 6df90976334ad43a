// The gRPC plumbing every farm process shares (coordinator, worker, CLI): status names and
// errors, channels with the farm's message limits, the bearer token, address checks.
#pragma once

#include <grpcpp/grpcpp.h>

#include <memory>
#include <stdexcept>
#include <string>

namespace lightfarm {

// Largest gRPC message either side accepts (task specs; blobs and results are chunked).
inline constexpr int kMaxMessageBytes = 64 << 20;

// A failed RPC; what() is "<CODE>: <message>", e.g. "UNAUTHENTICATED: missing or wrong ...".
class RpcError : public std::runtime_error {
 public:
  RpcError(const grpc::Status& status);
  grpc::StatusCode code() const { return code_; }

 private:
  grpc::StatusCode code_;
};

const char* StatusCodeName(grpc::StatusCode code);
void ThrowIfError(const grpc::Status& status);

struct ChannelOptions {
  std::string address;  // host:port
  bool tls = false;
  std::string tls_ca;   // PEM file with the root certificates; empty: the system's; given: TLS
};
std::shared_ptr<grpc::Channel> MakeChannel(const ChannelOptions& options);

// What is wrong with a HOST:PORT option value ("" when nothing): an empty host, a missing or
// non-numeric port, a port outside 1..65535 (0 too when `listen`: pick a free one). gRPC target
// URIs (unix:PATH, dns:, ipv4:, ipv6:) are passed through unchecked. Without this check a typo
// made the worker and the CLI retry an unreachable address until their timeout.
std::string HostPortProblem(const std::string& address, bool listen);

// Reads a token file (surrounding whitespace removed); "" for an empty path.
std::string ReadTokenFile(const std::string& path);

// Channel arguments both sides use: messages up to kMaxMessageBytes.
grpc::ChannelArguments FarmChannelArguments();

// "Bearer <token>" metadata check, constant time in the token's length.
bool TokenMatches(const std::string& expected, const std::string& header_value);

}  // namespace lightfarm
