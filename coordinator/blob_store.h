// Content-addressed blobs on disk: <dir>/<sha256>. Written to a temporary file and renamed, so a
// crash never leaves a partial blob under its name. A blob is checked against its name whenever
// it is read: one whose bytes no longer hash to it (a bad disk, a hand edit) is moved to
// <dir>/quarantine/ and is then missing, never served. Thread-safe.
#pragma once

#include <atomic>
#include <filesystem>
#include <vector>
#include <cstdint>
#include <fstream>
#include <memory>
#include <stdexcept>
#include <string>

#include "common/render/serialize.h"
#include "common/farm/content_hash.h"

namespace lightfarm {

// A blob whose bytes do not hash to its name; it has been quarantined (what() says where).
class BlobCorrupted : public std::runtime_error {
 public:
  BlobCorrupted(const std::string& message, std::string sha256)
      : std::runtime_error(message), sha256_(std::move(sha256)) {}
  const std::string& sha256() const { return sha256_; }

 private:
  std::string sha256_;
};

class BlobStore {
 public:
  BlobStore(std::string dir, uint64_t max_blob_bytes);

  bool Has(const std::string& sha256) const;
  std::string Path(const std::string& sha256) const { return dir_ + "/" + sha256; }
  uint64_t Size(const std::string& sha256) const;  // throws if missing
  // Stores bytes, returns their hash (when present and intact only touched; a corrupted copy is
  // quarantined and replaced).
  std::string Put(ByteView bytes);
  // Throws std::out_of_range when missing, BlobCorrupted (after quarantining it) when its bytes
  // do not hash to its name.
  Bytes Get(const std::string& sha256) const;
  // Re-hashes a stored blob: true when it is intact; false when it is missing or was corrupted
  // (then quarantined, logged and counted). For readers that stream the file from Path().
  bool Verify(const std::string& sha256) const;
  // Verify, throwing BlobCorrupted (std::out_of_range when missing): for readers that copy the file.
  void CheckIntact(const std::string& sha256) const;
  // Marks a stored blob as just used: the collection's grace period counts from it.
  void Touch(const std::string& sha256);
  struct Entry {
    std::string sha256;
    uint64_t size = 0;
    std::filesystem::file_time_type written;  // written or last touched
  };
  // Every stored blob (not the quarantined or temporary files).
  std::vector<Entry> List() const;
  // Removes a stored blob; its size, or 0 when it was not there.
  uint64_t Remove(const std::string& sha256);
  // Whether a file of `bytes` can be written here now (written to a temporary file and removed):
  // the coordinator's check that space has returned after a full disk.
  bool CanWrite(uint64_t bytes);
  // Blobs found corrupted and quarantined since the store opened.
  uint64_t corrupted() const { return corrupted_; }
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
  // Moves a blob that failed its hash check out of the store; returns the error to report.
  std::string Quarantine(const std::string& sha256, const std::string& got) const;
  std::string dir_;
  uint64_t max_blob_bytes_;
  std::atomic<uint64_t> temp_counter_{0};
  mutable std::atomic<uint64_t> corrupted_{0};
};

}  // namespace lightfarm
