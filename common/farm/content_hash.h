// SHA-256 content addresses (OpenSSL) for scene files, plan artifacts and results.
#pragma once

#include <cstdint>
#include <span>
#include <string>

typedef struct evp_md_ctx_st EVP_MD_CTX;

namespace lightfarm {

class Sha256 {
 public:
  Sha256();
  ~Sha256();
  Sha256(const Sha256&) = delete;
  Sha256& operator=(const Sha256&) = delete;
  void Update(const void* data, size_t size);
  std::string HexDigest();  // lower-case hex; call once

 private:
  EVP_MD_CTX* ctx_;
};

std::string Sha256Hex(std::span<const uint8_t> data);
std::string Sha256Hex(const std::string& data);
std::string Sha256OfFile(const std::string& path);  // throws std::runtime_error
bool IsSha256Hex(const std::string& s);

}  // namespace lightfarm
