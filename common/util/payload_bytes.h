// Byte encoding of stage payloads and artifacts inside one method (MRCS, LightSlice): plain
// values and arrays in host byte order (every farm machine here is little-endian x86-64/arm64;
// the farm's own messages use common/render/serialize.h). Reads are bounds-checked: a truncated or
// corrupt buffer throws std::runtime_error naming the method and the buffer, never reads past it.
#pragma once

#include <cstdint>
#include <bit>
#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

namespace lightfarm {

class PayloadWriter {
 public:
  template <typename T>
  void Put(const T& v) {
    Append(&v, sizeof(T));
  }
  template <typename T>
  void PutArray(const std::vector<T>& v) {
    Append(v.data(), v.size() * sizeof(T));
  }
  // A sparse row (the reduced rows of mrcs and lightslice): its count of non-zero entries, the
  // bitmap of where they are, and their values in order. PayloadReader::GetSparse reads it back.
  void PutSparse(const std::vector<uint64_t>& mask, const std::vector<float>& values) {
    Put(uint64_t(values.size()));
    PutArray(mask);
    PutArray(values);
  }
  std::vector<uint8_t> Take() { return std::move(bytes_); }

 private:
  void Append(const void* p, size_t n) {
    const uint8_t* b = static_cast<const uint8_t*>(p);
    bytes_.insert(bytes_.end(), b, b + n);
  }
  std::vector<uint8_t> bytes_;
};

class PayloadReader {
 public:
  // `owner` and `what` name the buffer in errors: "mrcs: truncated or corrupt cluster artifact".
  PayloadReader(const std::vector<uint8_t>& bytes, const char* owner, const char* what)
      : bytes_(bytes), owner_(owner), what_(what) {}
  template <typename T>
  T Get() {
    T v;
    std::memcpy(&v, Take(sizeof(T)), sizeof(T));
    return v;
  }
  template <typename T>
  void GetArray(std::vector<T>* v, size_t count) {
    if (count > (bytes_.size() - pos_) / sizeof(T)) Fail();
    v->resize(count);
    if (count == 0) return;  // an empty vector's data() may be null: no memcpy (UBSan)
    std::memcpy(v->data(), Take(count * sizeof(T)), count * sizeof(T));
  }
  // PayloadWriter::PutSparse's row, `words` bitmap words long; a bitmap whose set bits are not
  // the count of values is corrupt.
  void GetSparse(size_t words, std::vector<uint64_t>* mask, std::vector<float>* values) {
    const uint64_t count = Get<uint64_t>();
    GetArray(mask, words);
    GetArray(values, count);
    uint64_t bits = 0;
    for (uint64_t word : *mask) bits += uint64_t(std::popcount(word));
    if (bits != count) Fail();
  }
  void Skip(size_t n) { Take(n); }
  bool AtEnd() const { return pos_ == bytes_.size(); }

 private:
  const uint8_t* Take(size_t n) {
    if (n > bytes_.size() - pos_) Fail();
    const uint8_t* p = bytes_.data() + pos_;
    pos_ += n;
    return p;
  }
  [[noreturn]] void Fail() const {
    throw std::runtime_error(std::string(owner_) + ": truncated or corrupt " + what_);
  }
  const std::vector<uint8_t>& bytes_;
  const char* owner_;
  const char* what_;
  size_t pos_ = 0;
};

}  // namespace lightfarm
