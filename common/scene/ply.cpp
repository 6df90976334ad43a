// PLY reading and writing. The file is read into one buffer; the header becomes a list of
// typed elements, the element counts are checked against the bytes that follow, and then one
// pass over the data (ASCII tokens or binary values, dispatched by a template rather than a
// virtual call per value) fills the mesh.
#include "common/scene/ply.h"

#include <algorithm>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <iterator>
#include <limits>
#include <string_view>

#include "common/util/error.h"

namespace lightfarm {
namespace {

enum class PlyFormat { kAscii, kBinaryLittleEndian, kBinaryBigEndian };

enum class PlyType : uint8_t {
  kInt8,
  kUint8,
  kInt16,
  kUint16,
  kInt32,
  kUint32,
  kFloat32,
  kFloat64
};

struct PlyTypeName {
  std::string_view name;
  PlyType type;
};

// Both spellings of every type: the original ones and the sized ones of later writers.
constexpr PlyTypeName kPlyTypeNames[] = {
    {"char", PlyType::kInt8},       {"int8", PlyType::kInt8},       {"uchar", PlyType::kUint8},
    {"uint8", PlyType::kUint8},     {"short", PlyType::kInt16},     {"int16", PlyType::kInt16},
    {"ushort", PlyType::kUint16},   {"uint16", PlyType::kUint16},   {"int", PlyType::kInt32},
    {"int32", PlyType::kInt32},     {"uint", PlyType::kUint32},     {"uint32", PlyType::kUint32},
    {"float", PlyType::kFloat32},   {"float32", PlyType::kFloat32}, {"double", PlyType::kFloat64},
    {"float64", PlyType::kFloat64},
};

// Size and (for integer types) value range, indexed by PlyType.
struct PlyTypeInfo {
  int size;
  bool is_integer;
  int64_t min, max;
};
constexpr PlyTypeInfo kPlyTypeInfo[] = {
    {1, true, INT8_MIN, INT8_MAX},    // kInt8
    {1, true, 0, UINT8_MAX},          // kUint8
    {2, true, INT16_MIN, INT16_MAX},  // kInt16
    {2, true, 0, UINT16_MAX},         // kUint16
    {4, true, INT32_MIN, INT32_MAX},  // kInt32
    {4, true, 0, UINT32_MAX},         // kUint32
    {4, false, 0, 0},                 // kFloat32
    {8, false, 0, 0},                 // kFloat64
};
static_assert(std::size(kPlyTypeInfo) == static_cast<size_t>(PlyType::kFloat64) + 1);
const PlyTypeInfo& Info(PlyType type) { return kPlyTypeInfo[static_cast<int>(type)]; }
int TypeSize(PlyType type) { return Info(type).size; }
bool IsIntegerType(PlyType type) { return Info(type).is_integer; }

struct PlyProperty {
  std::string name;
  PlyType type = PlyType::kFloat32;  // the scalar type, or a list's item type
  bool is_list = false;
  PlyType count_type = PlyType::kUint8;  // lists only
  int line = 0;
};

struct PlyElement {
  std::string name;
  uint64_t count = 0;
  std::vector<PlyProperty> properties;
  int line = 0;
};

struct PlyHeader {
  PlyFormat format = PlyFormat::kAscii;
  std::vector<PlyElement> elements;
  size_t data_offset = 0;  // first byte after the end_header line
  int end_line = 0;
};

// Header text (names, types) shown in a message, cut short so garbage input stays readable.
std::string Quote(std::string_view text) {
  constexpr size_t kMaxShown = 40;
  std::string quoted = "\"" + std::string(text.substr(0, kMaxShown));
  if (text.size() > kMaxShown) quoted += "...";
  return quoted + "\"";
}

// A number for a message: shortest round-trip form, so 1e300 does not print 301 digits.
std::string NumberText(double value) {
  char text[32];
  auto [end, ec] = std::to_chars(text, text + sizeof(text), value);
  return std::string(text, end);
}

std::vector<std::string_view> SplitWords(std::string_view line) {
  std::vector<std::string_view> words;
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
    size_t start = i;
    while (i < line.size() && line[i] != ' ' && line[i] != '\t') ++i;
    if (i > start) words.push_back(line.substr(start, i - start));
  }
  return words;
}

bool ParseUint64(std::string_view text, uint64_t* value) {
  auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), *value);
  return ec == std::errc() && end == text.data() + text.size();
}

PlyHeader ParsePlyHeader(std::string_view bytes, const std::string& path) {
  auto error = [&](int line, const std::string& message) {
    return SceneError(FileLoc{path, line}, message);
  };
  // Real headers are a few dozen lines; the cap keeps the line counter far from overflow.
  constexpr int kMaxHeaderLines = 1'000'000;

  PlyHeader header;
  size_t pos = 0;
  int line_number = 0;
  // Next header line without its "\n" or "\r\n"; false when the bytes run out first.
  auto next_line = [&](std::string_view* line) {
    if (pos >= bytes.size() || line_number >= kMaxHeaderLines) return false;
    // The last line may lack its newline (an empty ASCII file ending in end_header)
    size_t newline = std::min(bytes.find('\n', pos), bytes.size());
    *line = bytes.substr(pos, newline - pos);
    if (!line->empty() && line->back() == '\r') line->remove_suffix(1);
    pos = std::min(newline + 1, bytes.size());
    ++line_number;
    return true;
  };

  // Check the magic
  std::string_view line;
  if (!next_line(&line) || line != "ply")
    throw error(1, "not a PLY file (the first line is not \"ply\")");

  // Read header lines up to end_header
  bool have_format = false;
  auto find_type = [&](std::string_view name, int at_line) {
    for (const PlyTypeName& t : kPlyTypeNames)
      if (t.name == name) return t.type;
    throw error(at_line, "unknown property type " + Quote(name));
  };
  while (true) {
    if (!next_line(&line))
      throw error(std::max(line_number, 1), "PLY header has no end_header line");
    std::vector<std::string_view> words = SplitWords(line);
    if (words.empty()) continue;
    std::string_view keyword = words[0];
    if (keyword == "comment" || keyword == "obj_info") continue;

    if (keyword == "format") {
      if (have_format) throw error(line_number, "second format line");
      if (words.size() != 3) throw error(line_number, "expected \"format <type> 1.0\"");
      if (words[1] == "ascii")
        header.format = PlyFormat::kAscii;
      else if (words[1] == "binary_little_endian")
        header.format = PlyFormat::kBinaryLittleEndian;
      else if (words[1] == "binary_big_endian")
        header.format = PlyFormat::kBinaryBigEndian;
      else
        throw error(line_number,
                    "unknown PLY format " + Quote(words[1]) +
                        " (expected ascii, binary_little_endian or binary_big_endian)");
      if (words[2] != "1.0") throw error(line_number, "unsupported PLY version " + Quote(words[2]));
      have_format = true;
    } else if (keyword == "element") {
      if (!have_format) throw error(line_number, "element before the format line");
      if (words.size() != 3) throw error(line_number, "expected \"element <name> <count>\"");
      PlyElement element;
      element.name = std::string(words[1]);
      element.line = line_number;
      if (!ParseUint64(words[2], &element.count))
        throw error(line_number, "bad element count " + Quote(words[2]));
      for (const PlyElement& other : header.elements)
        if (other.name == element.name)
          throw error(line_number, "second element named " + Quote(element.name));
      header.elements.push_back(std::move(element));
    } else if (keyword == "property") {
      if (header.elements.empty()) throw error(line_number, "property before any element");
      PlyProperty property;
      property.line = line_number;
      if (words.size() >= 2 && words[1] == "list") {
        if (words.size() != 5)
          throw error(line_number, "expected \"property list <count type> <item type> <name>\"");
        property.is_list = true;
        property.count_type = find_type(words[2], line_number);
        property.type = find_type(words[3], line_number);
        property.name = std::string(words[4]);
        if (!IsIntegerType(property.count_type))
          throw error(line_number,
                      "list count type " + Quote(words[2]) + " is not an integer type");
      } else {
        if (words.size() != 3) throw error(line_number, "expected \"property <type> <name>\"");
        property.type = find_type(words[1], line_number);
        property.name = std::string(words[2]);
      }
      PlyElement& element = header.elements.back();
      for (const PlyProperty& other : element.properties)
        if (other.name == property.name)
          throw error(line_number, "second property named " + Quote(property.name) +
                                       " in element " + Quote(element.name));
      element.properties.push_back(std::move(property));
    } else if (keyword == "end_header") {
      if (words.size() != 1) throw error(line_number, "unexpected text after end_header");
      break;
    } else {
      throw error(line_number, "unknown PLY header keyword " + Quote(keyword));
    }
  }
  if (!have_format) throw error(line_number, "PLY header has no format line");
  header.data_offset = pos;
  header.end_line = line_number;
  return header;
}

// Rejects counts the data cannot possibly hold, before anything is allocated: each binary
// element needs at least its scalar bytes plus its list counts; each ASCII property value needs
// one character and a separator.
void CheckCountsAgainstFileSize(const PlyHeader& header, size_t data_bytes,
                                const std::string& path) {
  bool ascii = header.format == PlyFormat::kAscii;
  uint64_t budget = ascii ? (uint64_t{data_bytes} + 1) / 2 : uint64_t{data_bytes};
  for (const PlyElement& element : header.elements) {
    uint64_t per_element = 0;
    for (const PlyProperty& p : element.properties)
      per_element += ascii ? 1 : TypeSize(p.is_list ? p.count_type : p.type);
    if (per_element == 0) continue;
    if (element.count > budget / per_element)
      throw SceneError(FileLoc{path, element.line},
                       "element " + Quote(element.name) + " declares " +
                           std::to_string(element.count) + " entries, but only " +
                           std::to_string(data_bytes) +
                           " bytes of data follow the header (truncated file or bad count)");
    budget -= element.count * per_element;
  }
}

// What the reader does with one property of the vertex or face element.
enum class Slot : uint8_t { kSkip, kX, kY, kZ, kNx, kNy, kNz, kU, kV, kFaceIndices };
constexpr int kSlotCount = 10;

struct MeshLayout {
  const PlyElement* vertex = nullptr;
  const PlyElement* face = nullptr;
  std::vector<Slot> vertex_slots;
  std::vector<Slot> face_slots;
  bool has_normals = false;
  bool has_uvs = false;
};

MeshLayout FindMeshLayout(const PlyHeader& header, const std::string& path) {
  auto error = [&](int line, const std::string& message) {
    return SceneError(FileLoc{path, line}, message);
  };
  MeshLayout layout;
  for (const PlyElement& element : header.elements) {
    if (element.name == "vertex") layout.vertex = &element;
    if (element.name == "face") layout.face = &element;
  }
  if (!layout.vertex) throw error(header.end_line, "PLY file has no vertex element");
  if (!layout.face) throw error(header.end_line, "PLY file has no face element");
  const PlyElement& vertex = *layout.vertex;
  if (vertex.count > static_cast<uint64_t>(std::numeric_limits<int>::max()))
    throw error(vertex.line, "too many vertices (" + std::to_string(vertex.count) + ")");

  // Assign vertex slots
  auto find = [](const PlyElement& element, std::string_view name) -> int {
    for (size_t i = 0; i < element.properties.size(); ++i)
      if (element.properties[i].name == name) return static_cast<int>(i);
    return -1;
  };
  layout.vertex_slots.assign(vertex.properties.size(), Slot::kSkip);
  auto assign_vertex = [&](int index, Slot slot) {
    const PlyProperty& p = vertex.properties[index];
    if (p.is_list)
      throw error(p.line, "vertex property " + Quote(p.name) + " must be a scalar, not a list");
    layout.vertex_slots[index] = slot;
  };
  // Optional attributes come as all-or-nothing groups; a partial group is a broken file.
  auto assign_group = [&](std::initializer_list<std::string_view> names,
                          std::initializer_list<Slot> slots) {
    std::vector<int> found;
    for (std::string_view name : names) found.push_back(find(vertex, name));
    int present =
        static_cast<int>(std::count_if(found.begin(), found.end(), [](int i) { return i >= 0; }));
    if (present == 0) return false;
    if (present != static_cast<int>(found.size())) {
      std::string list;
      for (std::string_view name : names) list += (list.empty() ? "" : " ") + std::string(name);
      int line = vertex.properties[*std::max_element(found.begin(), found.end())].line;
      throw error(line, "vertex element has only some of the properties " + list);
    }
    auto slot = slots.begin();
    for (int index : found) assign_vertex(index, *slot++);
    return true;
  };
  for (std::string_view name : {"x", "y", "z"})
    if (find(vertex, name) < 0)
      throw error(vertex.line, "vertex element has no " + std::string(name) + " property");
  assign_group({"x", "y", "z"}, {Slot::kX, Slot::kY, Slot::kZ});
  layout.has_normals = assign_group({"nx", "ny", "nz"}, {Slot::kNx, Slot::kNy, Slot::kNz});
  layout.has_uvs = assign_group({"u", "v"}, {Slot::kU, Slot::kV}) ||
                   assign_group({"s", "t"}, {Slot::kU, Slot::kV}) ||
                   assign_group({"texture_u", "texture_v"}, {Slot::kU, Slot::kV}) ||
                   assign_group({"texture_s", "texture_t"}, {Slot::kU, Slot::kV});

  // Find the face index list
  const PlyElement& face = *layout.face;
  int indices = find(face, "vertex_indices");
  if (indices < 0) indices = find(face, "vertex_index");
  if (indices < 0)
    throw error(face.line, "face element has no vertex_indices (or vertex_index) property");
  const PlyProperty& list = face.properties[indices];
  if (!list.is_list) throw error(list.line, "face property " + Quote(list.name) + " is not a list");
  if (!IsIntegerType(list.type))
    throw error(list.line, "face property " + Quote(list.name) + " has non-integer indices");
  layout.face_slots.assign(face.properties.size(), Slot::kSkip);
  layout.face_slots[indices] = Slot::kFaceIndices;
  return layout;
}

enum class ReadStatus { kOk, kEnd, kBadValue };

// Binary values in file order; kSwap when the file's byte order is not the machine's.
template <bool kSwap>
class BinaryValueReader {
 public:
  explicit BinaryValueReader(std::string_view data) : pos_(data.data()), end_(pos_ + data.size()) {}

  ReadStatus Read(PlyType type, double* value) {
    if (static_cast<size_t>(end_ - pos_) < static_cast<size_t>(TypeSize(type)))
      return ReadStatus::kEnd;
    switch (type) {
      case PlyType::kInt8:
        *value = Load<int8_t>();
        break;
      case PlyType::kUint8:
        *value = Load<uint8_t>();
        break;
      case PlyType::kInt16:
        *value = Load<int16_t>();
        break;
      case PlyType::kUint16:
        *value = Load<uint16_t>();
        break;
      case PlyType::kInt32:
        *value = Load<int32_t>();
        break;
      case PlyType::kUint32:
        *value = Load<uint32_t>();
        break;
      case PlyType::kFloat32:
        *value = static_cast<double>(Load<float>());
        break;
      case PlyType::kFloat64:
        *value = Load<double>();
        break;
    }
    return ReadStatus::kOk;
  }

  ReadStatus Skip(PlyType type, uint64_t count) {
    uint64_t size = static_cast<uint64_t>(TypeSize(type));
    if (count > static_cast<uint64_t>(end_ - pos_) / size) return ReadStatus::kEnd;
    pos_ += count * size;
    return ReadStatus::kOk;
  }

  std::string_view last_token() const { return {}; }
  bool AtEnd() const { return pos_ == end_; }
  size_t remaining() const { return static_cast<size_t>(end_ - pos_); }

 private:
  template <typename T>
  T Load() {
    char bytes[sizeof(T)];
    std::memcpy(bytes, pos_, sizeof(T));
    if constexpr (kSwap) std::reverse(bytes, bytes + sizeof(T));
    pos_ += sizeof(T);
    T value;
    std::memcpy(&value, bytes, sizeof(T));
    return value;
  }

  const char* pos_;
  const char* end_;
};

// ASCII values: whitespace-separated tokens, line breaks carry no meaning.
class AsciiValueReader {
 public:
  explicit AsciiValueReader(std::string_view data) : pos_(data.data()), end_(pos_ + data.size()) {}

  ReadStatus Read(PlyType type, double* value) {
    if (!NextToken()) return ReadStatus::kEnd;
    const char* first = token_.data();
    const char* last = first + token_.size();
    if (IsIntegerType(type)) {
      int64_t integer = 0;
      auto [end, ec] = std::from_chars(first, last, integer);
      if (ec != std::errc() || end != last || integer < Info(type).min || integer > Info(type).max)
        return ReadStatus::kBadValue;
      *value = static_cast<double>(integer);
    } else {
      auto [end, ec] = std::from_chars(first, last, *value);
      if (ec != std::errc() || end != last) return ReadStatus::kBadValue;
    }
    return ReadStatus::kOk;
  }

  ReadStatus Skip(PlyType, uint64_t count) {
    for (uint64_t i = 0; i < count; ++i)
      if (!NextToken()) return ReadStatus::kEnd;
    return ReadStatus::kOk;
  }

  std::string_view last_token() const { return token_; }
  bool AtEnd() {
    SkipSpace();
    return pos_ == end_;
  }
  size_t remaining() const { return static_cast<size_t>(end_ - pos_); }

 private:
  static bool IsSpace(char c) {
    return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\v' || c == '\f';
  }
  void SkipSpace() {
    while (pos_ != end_ && IsSpace(*pos_)) ++pos_;
  }
  bool NextToken() {
    SkipSpace();
    const char* start = pos_;
    while (pos_ != end_ && !IsSpace(*pos_)) ++pos_;
    token_ = std::string_view(start, static_cast<size_t>(pos_ - start));
    return !token_.empty();
  }

  const char* pos_;
  const char* end_;
  std::string_view token_;
};

// Reads the data section into a mesh. Every failure names the element and its index.
template <typename Reader>
class PlyDataReader {
 public:
  PlyDataReader(Reader* reader, const PlyHeader& header, const MeshLayout& layout,
                const std::string& path)
      : reader_(*reader), header_(header), layout_(layout), path_(path) {}

  PlyMesh Read() {
    PlyMesh mesh;
    for (const PlyElement& element : header_.elements) {
      if (&element == layout_.vertex)
        ReadVertices(element, &mesh);
      else if (&element == layout_.face)
        ReadFaces(element, &mesh);
      else
        SkipElement(element);
    }
    if (!reader_.AtEnd())
      throw SceneError(FileLoc{path_, 0},
                       std::to_string(reader_.remaining()) +
                           " bytes of unexpected data after the last element (element counts "
                           "in the header too small?)");
    return mesh;
  }

 private:
  SceneError ElementError(const PlyElement& element, uint64_t index, const std::string& message) {
    return SceneError(FileLoc{path_, 0},
                      element.name + " " + std::to_string(index) + ": " + message);
  }

  // One value of property p of element #index; throws at end of data or on a bad token.
  double Value(const PlyElement& element, uint64_t index, const PlyProperty& p, PlyType type) {
    double value = 0;
    switch (reader_.Read(type, &value)) {
      case ReadStatus::kOk:
        return value;
      case ReadStatus::kEnd:
        throw ElementError(element, index,
                           "unexpected end of file in property " + Quote(p.name) +
                               " (header "
                               "declares " +
                               std::to_string(element.count) + " " + element.name + " elements)");
      case ReadStatus::kBadValue:
        break;
    }
    throw ElementError(
        element, index,
        "bad value " + Quote(reader_.last_token()) + " for property " + Quote(p.name));
  }

  // A list's length; counts are integer-typed (checked in the header).
  int64_t ListCount(const PlyElement& element, uint64_t index, const PlyProperty& p) {
    int64_t count = static_cast<int64_t>(Value(element, index, p, p.count_type));
    if (count < 0)
      throw ElementError(element, index,
                         "negative list length " + std::to_string(count) + " in " + Quote(p.name));
    return count;
  }

  void SkipProperty(const PlyElement& element, uint64_t index, const PlyProperty& p) {
    uint64_t count = 1;
    if (p.is_list) count = static_cast<uint64_t>(ListCount(element, index, p));
    if (reader_.Skip(p.type, count) != ReadStatus::kOk)
      throw ElementError(element, index,
                         "unexpected end of file in property " + Quote(p.name) +
                             " (header "
                             "declares " +
                             std::to_string(element.count) + " " + element.name + " elements)");
  }

  void SkipElement(const PlyElement& element) {
    if (element.properties.empty()) return;
    for (uint64_t i = 0; i < element.count; ++i)
      for (const PlyProperty& p : element.properties) SkipProperty(element, i, p);
  }

  void ReadVertices(const PlyElement& element, PlyMesh* mesh) {
    mesh->positions.reserve(element.count);
    if (layout_.has_normals) mesh->normals.reserve(element.count);
    if (layout_.has_uvs) mesh->uvs.reserve(element.count);
    // A double outside float range would make the float conversion undefined.
    auto fits_float = [](double v) {
      return std::isfinite(v) && std::abs(v) <= double{std::numeric_limits<float>::max()};
    };
    double values[kSlotCount] = {};
    for (uint64_t i = 0; i < element.count; ++i) {
      for (size_t k = 0; k < element.properties.size(); ++k) {
        const PlyProperty& p = element.properties[k];
        Slot slot = layout_.vertex_slots[k];
        if (slot == Slot::kSkip)
          SkipProperty(element, i, p);
        else
          values[static_cast<int>(slot)] = Value(element, i, p, p.type);
      }
      auto triple = [&](Slot a, Slot b, Slot c, const char* what) {
        double x = values[static_cast<int>(a)], y = values[static_cast<int>(b)],
               z = values[static_cast<int>(c)];
        if (!fits_float(x) || !fits_float(y) || !fits_float(z))
          throw ElementError(element, i,
                             std::string("non-finite ") + what + " (" + NumberText(x) + ", " +
                                 NumberText(y) + ", " + NumberText(z) + ")");
        return Vec3(static_cast<float>(x), static_cast<float>(y), static_cast<float>(z));
      };
      mesh->positions.push_back(triple(Slot::kX, Slot::kY, Slot::kZ, "position"));
      if (layout_.has_normals)
        mesh->normals.push_back(triple(Slot::kNx, Slot::kNy, Slot::kNz, "normal"));
      if (layout_.has_uvs) {
        double u = values[static_cast<int>(Slot::kU)], v = values[static_cast<int>(Slot::kV)];
        if (!fits_float(u) || !fits_float(v))
          throw ElementError(element, i, "non-finite texture coordinate");
        mesh->uvs.push_back(Vec2(static_cast<float>(u), static_cast<float>(v)));
      }
    }
  }

  void ReadFaces(const PlyElement& element, PlyMesh* mesh) {
    const int64_t vertex_count = static_cast<int64_t>(layout_.vertex->count);
    mesh->indices.reserve(3 * element.count);
    int polygon[kPlyMaxPolygonVertices];
    for (uint64_t i = 0; i < element.count; ++i) {
      for (size_t k = 0; k < element.properties.size(); ++k) {
        const PlyProperty& p = element.properties[k];
        if (layout_.face_slots[k] != Slot::kFaceIndices) {
          SkipProperty(element, i, p);
          continue;
        }
        int64_t n = ListCount(element, i, p);
        if (n < 3)
          throw ElementError(element, i,
                             "has " + std::to_string(n) + " vertices (a face needs at least 3)");
        if (n > kPlyMaxPolygonVertices)
          throw ElementError(element, i,
                             "has " + std::to_string(n) + " vertices (more than " +
                                 std::to_string(kPlyMaxPolygonVertices) + " allowed)");
        for (int64_t j = 0; j < n; ++j) {
          int64_t index = static_cast<int64_t>(Value(element, i, p, p.type));
          if (index < 0 || index >= vertex_count)
            throw ElementError(element, i,
                               "vertex index " + std::to_string(index) + " out of range (" +
                                   std::to_string(vertex_count) + " vertices)");
          polygon[j] = static_cast<int>(index);
        }
        // Fan-triangulate around the first corner (faces are taken to be convex)
        for (int64_t j = 1; j + 1 < n; ++j) {
          mesh->indices.push_back(polygon[0]);
          mesh->indices.push_back(polygon[j]);
          mesh->indices.push_back(polygon[j + 1]);
        }
      }
    }
  }

  Reader& reader_;
  const PlyHeader& header_;
  const MeshLayout& layout_;
  const std::string& path_;
};

template <typename Reader>
PlyMesh ReadPlyData(std::string_view data, const PlyHeader& header, const MeshLayout& layout,
                    const std::string& path) {
  Reader reader(data);
  return PlyDataReader<Reader>(&reader, header, layout, path).Read();
}

std::string ReadFileBytes(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))
    throw SceneError(FileLoc{path, 0}, "cannot open PLY file (missing or not a regular file)");
  uintmax_t size = std::filesystem::file_size(path, ec);
  std::ifstream in(path, std::ios::binary);
  if (ec || !in) throw SceneError(FileLoc{path, 0}, "cannot open PLY file");
  std::string bytes(static_cast<size_t>(size), '\0');
  in.read(bytes.data(), static_cast<std::streamsize>(size));
  if (static_cast<uintmax_t>(in.gcount()) != size)
    throw SceneError(FileLoc{path, 0}, "error reading PLY file");
  return bytes;
}

// Little-endian bytes of a value, whatever the machine's byte order.
template <typename T>
void AppendLittleEndian(std::string* out, T value) {
  char bytes[sizeof(T)];
  std::memcpy(bytes, &value, sizeof(T));
  if constexpr (std::endian::native == std::endian::big) std::reverse(bytes, bytes + sizeof(T));
  out->append(bytes, sizeof(T));
}

// Shortest text that reads back as the same float.
void AppendFloatText(std::string* out, float value) {
  char text[32];
  auto [end, ec] = std::to_chars(text, text + sizeof(text), value);
  out->append(text, end);
}

}  // namespace

PlyMesh ReadPly(const std::string& path) {
  std::string bytes = ReadFileBytes(path);
  PlyHeader header = ParsePlyHeader(bytes, path);
  std::string_view data = std::string_view(bytes).substr(header.data_offset);
  CheckCountsAgainstFileSize(header, data.size(), path);
  MeshLayout layout = FindMeshLayout(header, path);

  constexpr bool kLittleHost = std::endian::native == std::endian::little;
  switch (header.format) {
    case PlyFormat::kAscii:
      return ReadPlyData<AsciiValueReader>(data, header, layout, path);
    case PlyFormat::kBinaryLittleEndian:
      return ReadPlyData<BinaryValueReader<!kLittleHost>>(data, header, layout, path);
    case PlyFormat::kBinaryBigEndian:
      return ReadPlyData<BinaryValueReader<kLittleHost>>(data, header, layout, path);
  }
  throw SceneError(FileLoc{path, 0}, "unsupported PLY format");
}

void WritePly(const std::string& path, const PlyMesh& mesh, const std::string& format) {
  auto error = [&](const std::string& message) { return SceneError(FileLoc{path, 0}, message); };
  bool ascii = format == "ascii";
  if (!ascii && format != "binary_little_endian")
    throw error("unsupported PLY output format " + Quote(format) +
                " (expected ascii or binary_little_endian)");

  // Check the mesh is consistent
  size_t vertex_count = mesh.positions.size();
  bool has_normals = !mesh.normals.empty();
  bool has_uvs = !mesh.uvs.empty();
  if (has_normals && mesh.normals.size() != vertex_count)
    throw error("mesh has " + std::to_string(mesh.normals.size()) + " normals for " +
                std::to_string(vertex_count) + " positions");
  if (has_uvs && mesh.uvs.size() != vertex_count)
    throw error("mesh has " + std::to_string(mesh.uvs.size()) + " uvs for " +
                std::to_string(vertex_count) + " positions");
  if (mesh.indices.size() % 3 != 0)
    throw error("mesh index count " + std::to_string(mesh.indices.size()) +
                " is not a multiple of 3");
  for (int index : mesh.indices)
    if (index < 0 || static_cast<size_t>(index) >= vertex_count)
      throw error("mesh vertex index " + std::to_string(index) + " out of range");

  // Header
  std::string out = "ply\nformat " + format + " 1.0\ncomment written by lightfarm\n";
  out += "element vertex " + std::to_string(vertex_count) + "\n";
  out += "property float x\nproperty float y\nproperty float z\n";
  if (has_normals) out += "property float nx\nproperty float ny\nproperty float nz\n";
  if (has_uvs) out += "property float u\nproperty float v\n";
  out += "element face " + std::to_string(mesh.indices.size() / 3) + "\n";
  out += "property list uchar int vertex_indices\nend_header\n";

  // Vertices and triangles
  for (size_t i = 0; i < vertex_count; ++i) {
    float values[8];
    int n = 0;
    for (int k = 0; k < 3; ++k) values[n++] = mesh.positions[i][k];
    if (has_normals)
      for (int k = 0; k < 3; ++k) values[n++] = mesh.normals[i][k];
    if (has_uvs) {
      values[n++] = mesh.uvs[i].x;
      values[n++] = mesh.uvs[i].y;
    }
    for (int k = 0; k < n; ++k) {
      if (ascii) {
        if (k > 0) out += ' ';
        AppendFloatText(&out, values[k]);
      } else {
        AppendLittleEndian(&out, values[k]);
      }
    }
    if (ascii) out += '\n';
  }
  for (size_t t = 0; t < mesh.indices.size(); t += 3) {
    if (ascii) {
      out += "3 " + std::to_string(mesh.indices[t]) + " " + std::to_string(mesh.indices[t + 1]) +
             " " + std::to_string(mesh.indices[t + 2]) + "\n";
    } else {
      AppendLittleEndian(&out, uint8_t{3});
      for (int k = 0; k < 3; ++k) AppendLittleEndian(&out, int32_t{mesh.indices[t + k]});
    }
  }

  std::ofstream file(path, std::ios::binary | std::ios::trunc);
  file.write(out.data(), static_cast<std::streamsize>(out.size()));
  file.close();
  if (!file) throw error("cannot write PLY file");
}

}  // namespace lightfarm
