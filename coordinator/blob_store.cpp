#include "coordinator/blob_store.h"

#include <unistd.h>

#include <spdlog/spdlog.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <stdexcept>

#include "coordinator/storage_full.h"

namespace lightfarm {

namespace fs = std::filesystem;

namespace {

// A write that failed: StorageFull when the disk is out of space (errno of the failed call),
// else an error naming the file.
[[noreturn]] void ThrowWriteError(const std::string& path, int err) {
  if (IsNoSpaceErrno(err)) throw StorageFull("blob store: no space left to write " + path);
  throw std::runtime_error("blob store: cannot write " + path + (err ? std::string(": ") + std::strerror(err) : ""));
}

}  // namespace

BlobStore::BlobStore(std::string dir, uint64_t max_blob_bytes)
    : dir_(std::move(dir)), max_blob_bytes_(max_blob_bytes) {
  fs::create_directories(dir_);
  fs::create_directories(dir_ + "/tmp");
  fs::create_directories(dir_ + "/quarantine");
  // Temporary files of a previous run are garbage.
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir_ + "/tmp", ec)) fs::remove(e.path(), ec);
}

bool BlobStore::Has(const std::string& sha256) const {
  return IsSha256Hex(sha256) && fs::exists(Path(sha256));
}

uint64_t BlobStore::Size(const std::string& sha256) const { return fs::file_size(Path(sha256)); }

std::string BlobStore::TempPath() {
  return dir_ + "/tmp/" + std::to_string(::getpid()) + "-" + std::to_string(temp_counter_++);
}

std::string BlobStore::Quarantine(const std::string& sha256, const std::string& got) const {
  ++corrupted_;
  // Several readers may find the same bad file: each moves what is there, under its own name.
  const std::string to = dir_ + "/quarantine/" + sha256 + "-" +
                         std::to_string(std::chrono::system_clock::now().time_since_epoch().count());
  std::error_code ec;
  fs::rename(Path(sha256), to, ec);
  const std::string message = "blob " + sha256 + " is corrupted on the coordinator's disk (its bytes hash to " +
                              got + "); quarantined as " + to;
  spdlog::error("blob store: {}", message);
  return message;
}

void BlobStore::CheckIntact(const std::string& sha256) const {
  if (!Has(sha256)) throw std::out_of_range("blob " + sha256 + " not found");
  const std::string got = Sha256OfFile(Path(sha256));
  if (got != sha256) throw BlobCorrupted(Quarantine(sha256, got), sha256);
}

bool BlobStore::Verify(const std::string& sha256) const {
  if (!Has(sha256)) return false;
  std::string got;
  try {
    got = Sha256OfFile(Path(sha256));
  } catch (const std::exception&) {
    return false;  // removed meanwhile, or unreadable: not servable either way
  }
  if (got == sha256) return true;
  Quarantine(sha256, got);
  return false;
}

void BlobStore::Touch(const std::string& sha256) {
  std::error_code ec;
  fs::last_write_time(Path(sha256), fs::file_time_type::clock::now(), ec);
}

std::vector<BlobStore::Entry> BlobStore::List() const {
  std::vector<Entry> out;
  std::error_code ec;
  for (auto it = fs::directory_iterator(dir_, ec); !ec && it != fs::directory_iterator(); it.increment(ec)) {
    const std::string name = it->path().filename().string();
    std::error_code e2;
    if (!IsSha256Hex(name) || !it->is_regular_file(e2)) continue;
    Entry entry{name, uint64_t(it->file_size(e2)), it->last_write_time(e2)};
    if (!e2) out.push_back(std::move(entry));
  }
  return out;
}

uint64_t BlobStore::Remove(const std::string& sha256) {
  std::error_code ec;
  const uint64_t size = fs::file_size(Path(sha256), ec);
  if (ec) return 0;
  return fs::remove(Path(sha256), ec) ? size : 0;
}

std::string BlobStore::Put(ByteView bytes) {
  std::string sha = Sha256Hex(bytes);
  if (Verify(sha)) {
    Touch(sha);  // in use again: not collected within the grace period
    return sha;
  }
  std::string tmp = TempPath();
  {
    errno = 0;
    std::ofstream f(tmp, std::ios::binary);
    f.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
    f.close();
    if (!f) {
      const int err = errno;
      std::error_code ec;
      fs::remove(tmp, ec);  // a partial file must not hold the space the next write needs
      ThrowWriteError(tmp, err);
    }
  }
  fs::rename(tmp, Path(sha));
  return sha;
}

bool BlobStore::CanWrite(uint64_t bytes) {
  const std::string tmp = TempPath();
  bool ok = false;
  {
    std::ofstream f(tmp, std::ios::binary);
    const std::string block(64 << 10, '\0');
    for (uint64_t left = bytes; f && left > 0; left -= std::min<uint64_t>(left, block.size()))
      f.write(block.data(), std::streamsize(std::min<uint64_t>(left, block.size())));
    f.close();
    ok = bool(f);
  }
  std::error_code ec;
  fs::remove(tmp, ec);
  return ok;
}

Bytes BlobStore::Get(const std::string& sha256) const {
  if (!Has(sha256)) throw std::out_of_range("blob " + sha256 + " not found");
  std::ifstream f(Path(sha256), std::ios::binary);
  Bytes data(fs::file_size(Path(sha256)));
  f.read(reinterpret_cast<char*>(data.data()), std::streamsize(data.size()));
  if (!f) throw std::runtime_error("blob store: cannot read " + sha256);
  const std::string got = Sha256Hex(data);
  if (got != sha256) throw BlobCorrupted(Quarantine(sha256, got), sha256);
  return data;
}

BlobStore::Upload::Upload(BlobStore* store, std::string expected_sha256, uint64_t expected_size)
    : store_(store), sha_(std::move(expected_sha256)), expected_size_(expected_size) {
  tmp_ = store_->TempPath();
  errno = 0;
  out_.open(tmp_, std::ios::binary);
  if (!out_) ThrowWriteError(tmp_, errno);
}

BlobStore::Upload::~Upload() {
  if (!committed_) {
    out_.close();
    std::error_code ec;
    fs::remove(tmp_, ec);
  }
}

void BlobStore::Upload::Append(const std::string& data) {
  size_ += data.size();
  if (size_ > expected_size_)
    throw std::length_error("blob " + sha_ + ": more data than the declared " +
                            std::to_string(expected_size_) + " bytes");
  hash_.Update(data.data(), data.size());
  errno = 0;
  out_.write(data.data(), std::streamsize(data.size()));
  if (!out_) ThrowWriteError(tmp_, errno);
}

void BlobStore::Upload::Commit() {
  if (size_ != expected_size_)
    throw std::invalid_argument("blob " + sha_ + ": received " + std::to_string(size_) +
                                " bytes, declared " + std::to_string(expected_size_));
  std::string got = hash_.HexDigest();
  if (got != sha_)
    throw std::invalid_argument("blob content hashes to " + got + ", not the declared " + sha_);
  errno = 0;
  out_.close();
  if (!out_) ThrowWriteError(tmp_, errno);
  fs::rename(tmp_, store_->Path(sha_));
  committed_ = true;
}

}  // namespace lightfarm
