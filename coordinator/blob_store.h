// Content-addressed blobs on disk: <dir>/<sha256>. Written to a temporary file and renamed, so a
// crash never leaves a partial blob under its name. Thread-safe.
#pragma once

#include <atomic>
#include <cstdint>
#include <fstream>
#include <memory>
#include <string>

#include "common/farm/serialize.h"
#include "common/farm/content_hash.h"

namespace lightfarm {

class BlobStore {
 public:
  BlobStore(std::string dir, uint64_t max_blob_bytes);

  bool Has(const std::string& sha256) const;
  std::string Path(const std::string& sha256) const { return dir_ + "/" + sha256; }
  uint64_t Size(const std::string& sha256) const;  // throws if missing
  // Stores bytes, returns their hash (no-op when present).
  std::string Put(ByteView bytes);
  Bytes Get(const std::string& sha256) const;  // throws std::out_of_range when missing
  uint64_t max_blob_bytes() const { return max_blob_bytes_; }

  // A streamed upload: Append chunks, then Commit checks size and hash.
  class Upload {
   public:
    Upload(BlobStore* store, std::string expected_sha256, uint64_t expected_size);
    ~Upload();
    void Append(const std::string& data);  // throws std::length_error past the declared size
    void Commit();                         // throws std::invalid_argument on a mismatch

   private:
    BlobStore* store_;
    std::string sha_, tmp_;
    uint64_t expected_size_, size_ = 0;
    std::ofstream out_;
    Sha256 hash_;
    bool committed_ = false;
  };

 private:
  std::string TempPath();
  std::string dir_;
  uint64_t max_blob_bytes_;
  std::atomic<uint64_t> temp_counter_{0};
};

}  // namespace lightfarm
