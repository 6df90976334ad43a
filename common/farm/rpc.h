// The gRPC plumbing every farm process shares (coordinator, worker, CLI): status names and
// errors, channels with the farm's message limits, the bearer token, address checks.
#pragma once

#include <grpcpp/grpcpp.h>

#include <algorithm>
#include <chrono>
#include <memory>
#include <stdexcept>
#include <string>

#include "common/farm/farm_protocol.h"

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

// Every client call: a deadline timeout_s from now and, when there is one, the bearer token.
void PrepareCall(grpc::ClientContext* ctx, const std::string& token, double timeout_s);

// Streams `size` bytes through a client writer in kChunkBytes messages (at least one, so an
// empty payload still sends its header); header(msg) fills the first message's other fields.
// Stops writing when the server ends the call early; returns the call's status.
template <typename Msg, typename Header>
grpc::Status WriteChunked(grpc::ClientWriter<Msg>& writer, const void* data, size_t size, Header header) {
  const char* bytes = static_cast<const char*>(data);
  size_t offset = 0;
  do {
    Msg chunk;
    if (offset == 0) header(chunk);
    const size_t n = std::min(kChunkBytes, size - offset);
    chunk.set_data(bytes + offset, n);
    offset += n;
    if (!writer.Write(chunk)) break;  // the server ended the call: Finish has its status
  } while (offset < size);
  writer.WritesDone();
  return writer.Finish();
}

}  // namespace lightfarm
