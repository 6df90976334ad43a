#include "common/farm/rpc.h"

#include <algorithm>
#include <cctype>

#include "common/util/file.h"

namespace lightfarm {

const char* StatusCodeName(grpc::StatusCode code) {
  switch (code) {
    case grpc::StatusCode::OK: return "OK";
    case grpc::StatusCode::CANCELLED: return "CANCELLED";
    case grpc::StatusCode::UNKNOWN: return "UNKNOWN";
    case grpc::StatusCode::INVALID_ARGUMENT: return "INVALID_ARGUMENT";
    case grpc::StatusCode::DEADLINE_EXCEEDED: return "DEADLINE_EXCEEDED";
    case grpc::StatusCode::NOT_FOUND: return "NOT_FOUND";
    case grpc::StatusCode::ALREADY_EXISTS: return "ALREADY_EXISTS";
    case grpc::StatusCode::PERMISSION_DENIED: return "PERMISSION_DENIED";
    case grpc::StatusCode::RESOURCE_EXHAUSTED: return "RESOURCE_EXHAUSTED";
    case grpc::StatusCode::FAILED_PRECONDITION: return "FAILED_PRECONDITION";
    case grpc::StatusCode::ABORTED: return "ABORTED";
    case grpc::StatusCode::OUT_OF_RANGE: return "OUT_OF_RANGE";
    case grpc::StatusCode::UNIMPLEMENTED: return "UNIMPLEMENTED";
    case grpc::StatusCode::INTERNAL: return "INTERNAL";
    case grpc::StatusCode::UNAVAILABLE: return "UNAVAILABLE";
    case grpc::StatusCode::DATA_LOSS: return "DATA_LOSS";
    case grpc::StatusCode::UNAUTHENTICATED: return "UNAUTHENTICATED";
    default: return "UNKNOWN";
  }
}

RpcError::RpcError(const grpc::Status& status)
    : std::runtime_error(std::string(StatusCodeName(status.error_code())) + ": " + status.error_message()),
      code_(status.error_code()) {}

void ThrowIfError(const grpc::Status& status) {
  if (!status.ok()) throw RpcError(status);
}

std::string HostPortProblem(const std::string& address, bool listen) {
  for (const char* scheme : {"unix:", "unix-abstract:", "dns:", "ipv4:", "ipv6:"})
    if (address.rfind(scheme, 0) == 0) return "";
  const size_t colon = address.rfind(':');
  if (colon == std::string::npos) return "\"" + address + "\" is not HOST:PORT";
  const std::string host = address.substr(0, colon), port = address.substr(colon + 1);
  if (host.empty() || host == "[]") return "\"" + address + "\" has no host (HOST:PORT)";
  if (port.empty() || port.size() > 5 || port.find_first_not_of("0123456789") != std::string::npos)
    return "\"" + address + "\": the port must be a number";
  const int value = std::stoi(port);
  if (value > 65535 || (value == 0 && !listen))
    return "\"" + address + "\": port " + port + (listen ? " is not in 0..65535" : " is not in 1..65535");
  return "";
}

std::shared_ptr<grpc::Channel> MakeChannel(const ChannelOptions& o) {
  std::shared_ptr<grpc::ChannelCredentials> creds;
  // A CA file means TLS: `--tls-ca F` alone must not fall back to plaintext (the worker did).
  if (o.tls || !o.tls_ca.empty()) {
    grpc::SslCredentialsOptions ssl;
    if (!o.tls_ca.empty()) ssl.pem_root_certs = ReadFile(o.tls_ca);
    creds = grpc::SslCredentials(ssl);
  } else {
    creds = grpc::InsecureChannelCredentials();
  }
  return grpc::CreateCustomChannel(o.address, creds, FarmChannelArguments());
}

std::string ReadTokenFile(const std::string& path) {
  if (path.empty()) return "";
  std::string t = ReadFile(path);
  const auto not_space = [](unsigned char c) { return !std::isspace(c); };
  t.erase(t.begin(), std::find_if(t.begin(), t.end(), not_space));
  t.erase(std::find_if(t.rbegin(), t.rend(), not_space).base(), t.end());
  if (t.empty()) throw std::runtime_error("token file " + path + " is empty");
  return t;
}

grpc::ChannelArguments FarmChannelArguments() {
  grpc::ChannelArguments args;
  args.SetMaxReceiveMessageSize(kMaxMessageBytes);
  args.SetMaxSendMessageSize(kMaxMessageBytes);
  return args;
}

void PrepareCall(grpc::ClientContext* ctx, const std::string& token, double timeout_s) {
  ctx->set_deadline(std::chrono::system_clock::now() + std::chrono::milliseconds(int64_t(timeout_s * 1000.0)));
  if (!token.empty()) ctx->AddMetadata("authorization", "Bearer " + token);
}

bool TokenMatches(const std::string& expected, const std::string& header_value) {
  const std::string want = "Bearer " + expected;
  unsigned diff = want.size() != header_value.size();
  for (size_t i = 0; i < want.size(); ++i)
    diff |= unsigned(uint8_t(want[i]) ^ uint8_t(i < header_value.size() ? header_value[i] : 0));
  return diff == 0;
}

}  // namespace lightfarm
