// pbrt-v4 scene files to SceneDescription: a tokenizer that knows the line and column of
// every token, and a directive interpreter that keeps pbrt-v4's graphics state (CTM, material,
// area light, media, attribute defaults) on an explicit stack. Nothing here builds geometry
// or reads PLY/image files; those are only recorded, so that the farm can ship them.
//
// Every error is a SceneError at the offending token. The input is treated as untrusted: file
// size, include depth and count, nesting depth and token and array lengths are capped, so a
// hostile file ends in an error, never in a crash, an exhausted machine or a hang.
#include <algorithm>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <memory>
#include <set>
#include <string_view>
#include <tuple>
#include <unordered_map>
#include <utility>

#include "common/scene/scene_description.h"

namespace lightfarm {

namespace fs = std::filesystem;

namespace {

// Limits against hostile input. Real scenes stay far below all of them.
constexpr uintmax_t kMaxFileBytes = uintmax_t(1) << 30;   // one file
constexpr uintmax_t kMaxTotalBytes = uintmax_t(4) << 30;  // all files, repeated includes counted
constexpr size_t kMaxIncludeDepth = 32;
// Bounds A-includes-B-twice-includes-C-twice... chains, which are not cycles but still explode.
constexpr int kMaxIncludeCount = 10000;
constexpr size_t kMaxTokenBytes = size_t(1) << 20;
constexpr size_t kMaxParamValues = size_t(1) << 26;  // 512 MiB of doubles
constexpr size_t kMaxBlockDepth = 10000;  // nested AttributeBegin/TransformBegin/ObjectBegin

std::string Quoted(std::string_view s) { return "\"" + std::string(s) + "\""; }

// Text from the file, made safe to put in an error message: bounded length, no control bytes.
std::string Printable(std::string_view s) {
  constexpr size_t kMax = 64;
  std::string out;
  for (size_t i = 0; i < s.size() && i < kMax; ++i) {
    unsigned char c = static_cast<unsigned char>(s[i]);
    out += (c >= 0x20 && c != 0x7f) ? static_cast<char>(c) : '?';
  }
  if (s.size() > kMax) out += "...";
  return out;
}

// ----------------------------------------------------------------------------------------------
// Tokenizer

struct Token {
  enum class Kind { kWord, kString, kOpenBracket, kCloseBracket };
  Kind kind = Kind::kWord;
  std::string_view word;  // kWord: a view into the file contents
  std::string str;        // kString: the contents with escapes decoded
  int line = 0, column = 0;

  bool IsWord(std::string_view w) const { return kind == Kind::kWord && word == w; }
  // What the token introduces, for "... expects ..." messages: a directive or a parameter.
  std::string Name() const {
    return kind == Kind::kString ? "parameter " + Quoted(Printable(str))
                                 : std::string(Printable(word));
  }
  // How the token appears in error messages.
  std::string Describe() const {
    switch (kind) {
      case Kind::kWord:
        return Quoted(Printable(word));
      case Kind::kString:
        return "string " + Quoted(Printable(str));
      case Kind::kOpenBracket:
        return "\"[\"";
      case Kind::kCloseBracket:
        return "\"]\"";
    }
    return "";
  }
};

// Splits one file into tokens: words (directives, numbers, true/false), quoted strings and
// brackets. Comments run from '#' to the end of the line.
class Tokenizer {
 public:
  Tokenizer(std::string contents, std::string filename)
      : contents_(std::move(contents)), filename_(std::move(filename)) {
    const auto* b = reinterpret_cast<const unsigned char*>(contents_.data());
    if (contents_.size() >= 2 && ((b[0] == 0xfe && b[1] == 0xff) || (b[0] == 0xff && b[1] == 0xfe)))
      throw SceneError(LocAt(1, 1), "file is UTF-16 encoded; scene files must be UTF-8 or ASCII");
    if (contents_.size() >= 3 && b[0] == 0xef && b[1] == 0xbb && b[2] == 0xbf)
      pos_ = 3;  // UTF-8 BOM
    line_start_ = pos_;
  }

  const std::string& filename() const { return filename_; }
  // Line of the last token returned (1 before any), for errors about what is missing at the end.
  int last_token_line() const { return last_token_line_; }
  FileLoc LocAt(int line, int column) const { return FileLoc{filename_, line, column}; }
  FileLoc Loc(const Token& t) const { return LocAt(t.line, t.column); }

  std::optional<Token> Next() {
    SkipSpaceAndComments();
    if (pos_ >= contents_.size()) return std::nullopt;

    Token t;
    t.line = line_;
    t.column = static_cast<int>(pos_ - line_start_) + 1;
    last_token_line_ = line_;
    char c = contents_[pos_];
    if (c == '[' || c == ']') {
      t.kind = c == '[' ? Token::Kind::kOpenBracket : Token::Kind::kCloseBracket;
      ++pos_;
    } else if (c == '"') {
      t.kind = Token::Kind::kString;
      ReadString(&t);
    } else {
      size_t start = pos_;
      while (pos_ < contents_.size() && !IsSpace(contents_[pos_]) && !IsDelimiter(contents_[pos_]))
        ++pos_;
      t.word = std::string_view(contents_).substr(start, pos_ - start);
      if (t.word.size() > kMaxTokenBytes)
        throw SceneError(Loc(t), "token longer than " + std::to_string(kMaxTokenBytes) + " bytes");
    }
    return t;
  }

 private:
  static bool IsSpace(char c) {
    return c == ' ' || c == '\n' || c == '\t' || c == '\r' || c == '\f' || c == '\v';
  }
  static bool IsDelimiter(char c) { return c == '"' || c == '[' || c == ']' || c == '#'; }

  void SkipSpaceAndComments() {
    while (pos_ < contents_.size()) {
      char c = contents_[pos_];
      if (c == '\n') {
        ++pos_;
        ++line_;
        line_start_ = pos_;
      } else if (IsSpace(c)) {
        ++pos_;
      } else if (c == '#') {
        while (pos_ < contents_.size() && contents_[pos_] != '\n') ++pos_;
      } else {
        return;
      }
    }
  }

  // Reads a quoted string starting at the opening quote; decodes pbrt's escapes.
  void ReadString(Token* t) {
    ++pos_;  // opening quote
    while (true) {
      if (pos_ >= contents_.size())
        throw SceneError(Loc(*t), "unterminated string (end of file before the closing quote)");
      char c = contents_[pos_++];
      if (c == '"') break;
      if (c == '\n')
        throw SceneError(Loc(*t), "unterminated string (newline before the closing quote)");
      if (c == '\\') {
        if (pos_ >= contents_.size())
          throw SceneError(Loc(*t), "unterminated string (end of file after '\\')");
        // pbrt's escapes, as (letter, character) pairs: \b \f \n \r \t \\ \' \"
        static constexpr std::string_view kEscapes = "b\bf\fn\nr\rt\t\\\\''\"\"";
        char e = contents_[pos_++];
        size_t i = 0;
        while (i < kEscapes.size() && kEscapes[i] != e) i += 2;
        if (i >= kEscapes.size())
          throw SceneError(Loc(*t), "unknown escape sequence \"\\" + Printable(std::string(1, e)) +
                                        "\" in string");
        c = kEscapes[i + 1];
      }
      t->str.push_back(c);
      if (t->str.size() > kMaxTokenBytes)
        throw SceneError(Loc(*t),
                         "string longer than " + std::to_string(kMaxTokenBytes) + " bytes");
    }
  }

  std::string contents_;
  std::string filename_;
  size_t pos_ = 0;
  int line_ = 1;
  size_t line_start_ = 0;
  int last_token_line_ = 1;
};

// Reads a whole file. `where` is the location that asked for it (an Include), or a location
// naming just the file for the root.
std::string ReadFileContents(const std::string& path, const FileLoc& where,
                             const std::string& what) {
  std::error_code ec;
  fs::file_status st = fs::status(path, ec);
  if (ec || !fs::exists(st))
    throw SceneError(where, "cannot open " + what + ": " + Quoted(path) + " does not exist");
  if (!fs::is_regular_file(st))
    throw SceneError(where, "cannot open " + what + ": " + Quoted(path) + " is not a regular file");
  uintmax_t size = fs::file_size(path, ec);
  if (ec) throw SceneError(where, "cannot open " + what + " " + Quoted(path) + ": " + ec.message());
  if (size > kMaxFileBytes)
    throw SceneError(where, what + " " + Quoted(path) + " is larger than 1 GiB");
  std::ifstream in(path, std::ios::binary);
  if (!in)
    throw SceneError(where,
                     "cannot open " + what + " " + Quoted(path) + ": " + std::strerror(errno));
  std::string contents(static_cast<size_t>(size), '\0');
  in.read(contents.data(), static_cast<std::streamsize>(size));
  if (static_cast<uintmax_t>(in.gcount()) != size)
    throw SceneError(where, "error reading " + what + " " + Quoted(path));
  return contents;
}

// ----------------------------------------------------------------------------------------------
// Directive interpreter

class SceneParser {
 public:
  SceneParser(std::string root_file, std::string base_dir) {
    scene_.root_file = std::move(root_file);
    scene_.base_dir = std::move(base_dir);
    // pbrt-v4's defaults for directives a file may leave out.
    scene_.camera.type = "perspective";
    scene_.film.type = "rgb";
    scene_.filter.type = "gaussian";
    scene_.sampler.type = "zsobol";
    scene_.integrator.type = "volpath";
    scene_.accelerator.type = "bvh";
  }

  // Parses `contents` as the root file. `identity` is its canonical path, used to detect an
  // Include cycle back to the root ("" for in-memory text).
  SceneDescription Parse(std::string contents, const std::string& identity) {
    total_bytes_ = contents.size();
    PushFile(std::make_unique<Tokenizer>(std::move(contents), scene_.root_file), identity, false);
    while (!files_.empty()) {
      std::optional<Token> tok = NextToken();
      if (!tok) {
        CloseFile();
        continue;
      }
      Dispatch(*tok);
    }
    Finish();
    return std::move(scene_);
  }

  void AddFile(const std::string& path) {
    if (files_seen_.insert(path).second) scene_.files.push_back(path);
  }

 private:
  // Graphics state: what AttributeBegin saves and AttributeEnd restores.
  struct GraphicsState {
    Transform ctm;
    bool reverse_orientation = false;
    int material = -1;  // -1: pbrt-v4's default "diffuse" material (see ShapeDesc::material)
    std::optional<TypedEntity> area_light;
    int medium_interface = -1;  // index into medium_interfaces_, -1: no media
    ParamSet shape_defaults, light_defaults, material_defaults, medium_defaults, texture_defaults;
  };

  struct Block {
    enum class Kind { kAttribute, kTransform, kObject };
    Kind kind;
    FileLoc loc;
    GraphicsState saved;
  };

  struct OpenFile {
    std::unique_ptr<Tokenizer> tokens;
    std::string identity;  // canonical path, for cycle detection
    bool is_import = false;
    GraphicsState saved;     // Import only: the state to restore at its end
    size_t block_floor = 0;  // blocks_ below this index belong to an importing file
  };

  // A MediumInterface directive. Media may be defined after the MediumInterface that names
  // them (pbrt-v4 resolves names when it builds the scene), so the names are checked at the
  // end, and only if a Shape, LightSource or Camera actually used them.
  struct MediumInterfaceUse {
    std::string inside, outside;
    FileLoc loc;
    std::optional<FileLoc> first_use;
  };

  using Handler = void (SceneParser::*)(const Token&);

  // --- Tokens --------------------------------------------------------------------------------

  // The next token of the current file. A directive never continues into the next file: the
  // main loop alone moves between files, so no token outlives the file it points into.
  std::optional<Token> NextToken() {
    if (unget_) return std::exchange(unget_, std::nullopt);
    return files_.back().tokens->Next();
  }
  void Unget(Token t) { unget_ = std::move(t); }

  FileLoc Loc(const Token& t) const { return files_.back().tokens->Loc(t); }
  [[noreturn]] void Fail(const Token& t, const std::string& message) const {
    throw SceneError(Loc(t), message);
  }

  Token Expect(const Token& directive, const std::string& what) {
    std::optional<Token> t = NextToken();
    if (!t) Fail(directive, "unexpected end of file: " + directive.Name() + " expects " + what);
    return std::move(*t);
  }

  Token ExpectStringToken(const Token& directive, const std::string& what) {
    Token t = Expect(directive, what);
    if (t.kind != Token::Kind::kString)
      Fail(t, std::string(directive.word) + " expects " + what + " (a quoted string), got " +
                  t.Describe());
    return t;
  }
  std::string ExpectString(const Token& directive, const std::string& what) {
    return ExpectStringToken(directive, what).str;
  }

  double ParseNumber(const Token& t) const {
    if (t.kind != Token::Kind::kWord) Fail(t, "expected a number, got " + t.Describe());
    std::string_view s = t.word;
    if (!s.empty() && s[0] == '+') s.remove_prefix(1);
    double v = 0;
    const char* end = s.data() + s.size();
    auto [ptr, ec] = std::from_chars(s.data(), end, v);
    if (s.empty() || ptr != end || (ec != std::errc() && ec != std::errc::result_out_of_range))
      Fail(t, "malformed number " + Quoted(Printable(t.word)));
    if (ec == std::errc::result_out_of_range) {
      // from_chars reports underflow too; a value too small for a double is a harmless zero,
      // one too large is not.
      errno = 0;
      double r = std::strtod(std::string(s).c_str(), nullptr);
      if (std::isinf(r)) Fail(t, "number out of range: " + Printable(t.word));
      v = r;
    }
    if (!std::isfinite(v))
      Fail(t, "malformed number " + Quoted(Printable(t.word)) + " (not finite)");
    // The renderer works in float: a larger magnitude would turn into infinity downstream.
    if (std::abs(v) > double(std::numeric_limits<float>::max()))
      Fail(t, "number out of range: " + Printable(t.word) + " does not fit in a float");
    return v;
  }

  double ExpectNumber(const Token& directive) { return ParseNumber(Expect(directive, "a number")); }

  // --- Parameter lists -----------------------------------------------------------------------

  enum class ValueKind { kNumber, kBool, kString, kNumberOrString };

  static std::optional<ValueKind> ParamValueKind(const std::string& type) {
    static const std::unordered_map<std::string, ValueKind> kTypes = {
        {"integer", ValueKind::kNumber},
        {"float", ValueKind::kNumber},
        {"point2", ValueKind::kNumber},
        {"vector2", ValueKind::kNumber},
        {"point3", ValueKind::kNumber},
        {"vector3", ValueKind::kNumber},
        {"normal3", ValueKind::kNumber},
        {"normal", ValueKind::kNumber},
        {"point", ValueKind::kNumber},
        {"vector", ValueKind::kNumber},
        {"rgb", ValueKind::kNumber},
        {"color", ValueKind::kNumber},
        {"blackbody", ValueKind::kNumber},
        {"bool", ValueKind::kBool},
        {"string", ValueKind::kString},
        {"texture", ValueKind::kString},
        {"spectrum", ValueKind::kNumberOrString},
    };
    auto it = kTypes.find(type);
    if (it == kTypes.end()) return std::nullopt;
    return it->second;
  }

  // Reads "type name" declarations and their values until the next directive.
  ParamSet ParseParams() {
    ParamSet params;
    while (true) {
      std::optional<Token> t = NextToken();
      if (!t) break;
      if (t->kind != Token::Kind::kString) {
        Unget(std::move(*t));
        break;
      }
      Param p = ParseParam(*t);
      // ParamSet::Add would let the second silently replace the first; in a single directive a
      // repeated name is a mistake (pbrt-v4 reports the second as unused).
      if (const Param* first = params.Find(p.name))
        throw SceneError(p.loc, "parameter " + Quoted(p.name) + " given twice (first at line " +
                                    std::to_string(first->loc.line) + ")");
      params.Add(std::move(p));
    }
    return params;
  }

  Param ParseParam(const Token& decl) {
    Param p;
    p.loc = Loc(decl);
    // The declaration is exactly two words: "type name".
    std::vector<std::string> words;
    {
      std::string w;
      for (char c : decl.str) {
        if (c == ' ' || c == '\t') {
          if (!w.empty()) words.push_back(std::move(w));
          w.clear();
        } else {
          w.push_back(c);
        }
      }
      if (!w.empty()) words.push_back(std::move(w));
    }
    if (words.size() != 2)
      Fail(decl, "parameter declaration " + Quoted(Printable(decl.str)) +
                     " must be \"type name\"; expected a parameter or a directive");
    p.type = words[0];
    p.name = words[1];
    std::optional<ValueKind> kind = ParamValueKind(p.type);
    if (!kind)
      Fail(decl, "unknown parameter type " + Quoted(Printable(p.type)) + " in " +
                     Quoted(Printable(decl.str)));

    Token first = Expect(decl, "a value for parameter " + Quoted(p.name));
    if (first.kind == Token::Kind::kOpenBracket) {
      while (true) {
        std::optional<Token> v = NextToken();
        if (!v) Fail(first, "unclosed \"[\" in the values of parameter " + Quoted(p.name));
        if (v->kind == Token::Kind::kCloseBracket) break;
        AddValue(&p, *kind, *v);
      }
    } else {
      AddValue(&p, *kind, first);
    }
    CheckValueCount(p);
    return p;
  }

  void AddValue(Param* p, ValueKind kind, const Token& v) const {
    if (p->numbers.size() + p->strings.size() + p->bools.size() >= kMaxParamValues)
      Fail(v, "parameter " + Quoted(p->name) + " has more than " + std::to_string(kMaxParamValues) +
                  " values");
    switch (kind) {
      case ValueKind::kNumber:
      case ValueKind::kNumberOrString:
        if (v.kind == Token::Kind::kString && kind == ValueKind::kNumberOrString) {
          if (!p->numbers.empty())
            Fail(v, "parameter " + Quoted(p->name) + " mixes numbers and strings");
          p->strings.push_back(v.str);
          return;
        }
        if (v.kind != Token::Kind::kWord)
          Fail(v, "parameter " + Quoted(p->type + " " + p->name) + " expects numbers, got " +
                      v.Describe());
        if (!p->strings.empty())
          Fail(v, "parameter " + Quoted(p->name) + " mixes numbers and strings");
        {
          double x = ParseNumber(v);
          if (p->type == "integer" && (x != std::floor(x) || std::abs(x) > 2147483647.0))
            Fail(v, "parameter " + Quoted(p->type + " " + p->name) + " expects integers, got " +
                        Printable(v.word));
          p->numbers.push_back(x);
        }
        return;
      case ValueKind::kBool: {
        // true/false, bare as pbrt-v4 writes them or quoted as pbrt-v3 did.
        std::string_view text = v.kind == Token::Kind::kString ? std::string_view(v.str)
                                : v.kind == Token::Kind::kWord ? v.word
                                                               : std::string_view();
        if (text == "true")
          p->bools.push_back(true);
        else if (text == "false")
          p->bools.push_back(false);
        else
          Fail(v, "parameter " + Quoted(p->type + " " + p->name) + " expects true or false, got " +
                      v.Describe());
        return;
      }
      case ValueKind::kString:
        if (v.kind != Token::Kind::kString)
          Fail(v, "parameter " + Quoted(p->type + " " + p->name) + " expects quoted strings, got " +
                      v.Describe());
        p->strings.push_back(v.str);
        return;
    }
  }

  // The number of values each type takes; errors name the parameter's declaration.
  static void CheckValueCount(const Param& p) {
    size_t n = p.numbers.size() + p.strings.size() + p.bools.size();
    auto fail = [&](const std::string& expectation) {
      throw SceneError(p.loc, "parameter " + Quoted(p.type + " " + p.name) + " " + expectation +
                                  ", got " + std::to_string(n));
    };
    const std::string& t = p.type;
    if (n == 0) fail("needs at least one value");
    if (t == "point2" || t == "vector2") {
      if (n % 2 != 0) fail("needs a multiple of 2 numbers");
    } else if (t == "point3" || t == "vector3" || t == "normal3" || t == "normal" || t == "point" ||
               t == "vector") {
      if (n % 3 != 0) fail("needs a multiple of 3 numbers");
    } else if (t == "rgb" || t == "color") {
      if (n != 3) fail("needs exactly 3 numbers");
    } else if (t == "blackbody") {
      if (n != 1) fail("needs exactly one temperature (pbrt-v4 dropped the scale value)");
    } else if (t == "texture") {
      if (n != 1) fail("needs exactly one texture name");
    } else if (t == "spectrum") {
      if (!p.strings.empty() && n != 1) fail("needs exactly one spectrum name");
      if (p.strings.empty() && n % 2 != 0) fail("needs (wavelength, value) pairs");
    }
  }

  // Records a referenced file ("string filename" of a plymesh, imagemap, ...) without marking
  // the parameter used: the builder reads it and is the one to report it if it does not.
  void RecordFileParam(const ParamSet& params, const char* name) {
    const Param* p = params.Find(name);
    if (p && p->type == "string" && p->strings.size() == 1 && !p->strings[0].empty())
      AddFile(scene_.ResolvePath(p->strings[0]));
  }

  // Copies `params` without the "string type" parameter, which Make* directives turn into the
  // entity's type.
  static ParamSet WithoutType(const ParamSet& params) {
    ParamSet out;
    for (const Param& p : params.params())
      if (p.name != "type") out.Add(p);
    return out;
  }

  // --- Files ---------------------------------------------------------------------------------

  void PushFile(std::unique_ptr<Tokenizer> tokens, std::string identity, bool is_import) {
    OpenFile f;
    f.tokens = std::move(tokens);
    f.identity = std::move(identity);
    f.is_import = is_import;
    if (is_import) {
      f.saved = gs_;
      f.block_floor = blocks_.size();
    } else {
      f.block_floor = files_.empty() ? 0 : files_.back().block_floor;
    }
    files_.push_back(std::move(f));
  }

  void OpenIncluded(const Token& directive, bool is_import) {
    Token name_tok = ExpectStringToken(directive, "a file name");
    if (files_.size() >= kMaxIncludeDepth + 1)
      Fail(directive, std::string(directive.word) + " nested deeper than " +
                          std::to_string(kMaxIncludeDepth) + " files");
    if (++include_count_ > kMaxIncludeCount)
      Fail(directive,
           "more than " + std::to_string(kMaxIncludeCount) + " Include/Import directives");
    std::string path = scene_.ResolvePath(name_tok.str);

    std::error_code ec;
    std::string identity = fs::weakly_canonical(path, ec).string();
    if (ec) identity = fs::absolute(path, ec).lexically_normal().string();
    for (size_t i = 0; i < files_.size(); ++i) {
      if (files_[i].identity.empty() || files_[i].identity != identity) continue;
      std::string chain;
      for (size_t j = i; j < files_.size(); ++j) chain += files_[j].tokens->filename() + " -> ";
      Fail(name_tok, "recursive " + std::string(directive.word) + ": " + chain + path);
    }

    std::string contents =
        ReadFileContents(path, Loc(name_tok), "included file " + Quoted(name_tok.str));
    total_bytes_ += contents.size();
    if (total_bytes_ > kMaxTotalBytes)
      Fail(directive, "scene files total more than 4 GiB (repeated Include?)");
    AddFile(path);
    PushFile(std::make_unique<Tokenizer>(std::move(contents), path), identity, is_import);
  }

  void CloseFile() {
    OpenFile& f = files_.back();
    if (f.is_import) {
      // Import, unlike Include, parses into a copy of the graphics state (pbrt-v4): blocks must
      // balance inside the file, and nothing it sets leaks into the importing file.
      if (blocks_.size() > f.block_floor)
        throw SceneError(blocks_.back().loc,
                         BlockName(blocks_.back().kind) + " is never closed in the imported file");
      gs_ = f.saved;
    }
    if (files_.size() == 1) end_of_root_ = f.tokens->LocAt(f.tokens->last_token_line(), 0);
    files_.pop_back();
  }

  // --- Graphics state helpers ----------------------------------------------------------------

  static std::string BlockName(Block::Kind k) {
    switch (k) {
      case Block::Kind::kAttribute:
        return "AttributeBegin";
      case Block::Kind::kTransform:
        return "TransformBegin";
      case Block::Kind::kObject:
        return "ObjectBegin";
    }
    return "";
  }

  void VerifyWorld(const Token& t) const {
    if (!in_world_) Fail(t, std::string(t.word) + " is only allowed after WorldBegin");
  }
  void VerifyOptions(const Token& t) const {
    if (in_world_) Fail(t, std::string(t.word) + " must come before WorldBegin");
  }

  void PushBlock(const Token& t, Block::Kind kind) {
    if (blocks_.size() >= kMaxBlockDepth)
      Fail(t, std::string(t.word) + " nested deeper than " + std::to_string(kMaxBlockDepth));
    blocks_.push_back(Block{kind, Loc(t), gs_});
  }

  // Pops the innermost block, which must be of `kind`.
  Block PopBlock(const Token& t, Block::Kind kind) {
    if (blocks_.size() <= files_.back().block_floor)
      Fail(t, std::string(t.word) + " without a matching " + BlockName(kind));
    if (blocks_.back().kind != kind)
      Fail(t, std::string(t.word) + " closes " + BlockName(blocks_.back().kind) + " opened at " +
                  blocks_.back().loc.ToString());
    Block b = std::move(blocks_.back());
    blocks_.pop_back();
    return b;
  }

  // Names of the media in force, recording the first user so that unknown names are reported.
  std::pair<std::string, std::string> UseMedia(const Token& user) {
    if (gs_.medium_interface < 0) return {};
    MediumInterfaceUse& mi = medium_interfaces_[gs_.medium_interface];
    if (!mi.first_use) mi.first_use = Loc(user);
    return {mi.inside, mi.outside};
  }

  void ConcatenateCTM(const Transform& t) { gs_.ctm = gs_.ctm * t; }

  // pbrt writes matrices with the translation in elements 12..14, i.e. the transpose of the
  // row-major matrix that transforms column vectors.
  Transform ReadMatrix(const Token& directive) {
    Token open = Expect(directive, "\"[\" and 16 numbers");
    if (open.kind != Token::Kind::kOpenBracket)
      Fail(open,
           std::string(directive.word) + " expects \"[\" and 16 numbers, got " + open.Describe());
    double v[16];
    int n = 0;
    while (true) {
      Token t = Expect(directive, "\"]\"");
      if (t.kind == Token::Kind::kCloseBracket) break;
      if (n == 16) Fail(t, std::string(directive.word) + " takes 16 numbers, got more");
      v[n++] = ParseNumber(t);
    }
    if (n != 16)
      Fail(directive, std::string(directive.word) + " takes 16 numbers, got " + std::to_string(n));
    Transform::Matrix m;
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j) m[i][j] = v[j * 4 + i];
    return Transform(m);
  }

  // --- Directives ----------------------------------------------------------------------------

  void Dispatch(const Token& t) {
    static const std::unordered_map<std::string_view, Handler> kDirectives = {
        {"Accelerator", &SceneParser::Accelerator},
        {"ActiveTransform", &SceneParser::ActiveTransform},
        {"AreaLightSource", &SceneParser::AreaLightSource},
        {"Attribute", &SceneParser::Attribute},
        {"AttributeBegin", &SceneParser::AttributeBegin},
        {"AttributeEnd", &SceneParser::AttributeEnd},
        {"Camera", &SceneParser::Camera},
        {"ColorSpace", &SceneParser::ColorSpace},
        {"ConcatTransform", &SceneParser::ConcatTransform},
        {"CoordinateSystem", &SceneParser::CoordinateSystem},
        {"CoordSysTransform", &SceneParser::CoordSysTransform},
        {"Film", &SceneParser::Film},
        {"Identity", &SceneParser::Identity},
        {"Import", &SceneParser::Import},
        {"Include", &SceneParser::Include},
        {"Integrator", &SceneParser::Integrator},
        {"LightSource", &SceneParser::LightSource},
        {"LookAt", &SceneParser::LookAt},
        {"MakeNamedMaterial", &SceneParser::MakeNamedMaterial},
        {"MakeNamedMedium", &SceneParser::MakeNamedMedium},
        {"Material", &SceneParser::Material},
        {"MediumInterface", &SceneParser::MediumInterface},
        {"NamedMaterial", &SceneParser::NamedMaterial},
        {"ObjectBegin", &SceneParser::ObjectBegin},
        {"ObjectEnd", &SceneParser::ObjectEnd},
        {"ObjectInstance", &SceneParser::ObjectInstance},
        {"Option", &SceneParser::Option},
        {"PixelFilter", &SceneParser::PixelFilter},
        {"ReverseOrientation", &SceneParser::ReverseOrientation},
        {"Rotate", &SceneParser::Rotate},
        {"Sampler", &SceneParser::Sampler},
        {"Scale", &SceneParser::Scale},
        {"Shape", &SceneParser::Shape},
        {"Texture", &SceneParser::Texture},
        {"Transform", &SceneParser::TransformDirective},
        {"TransformBegin", &SceneParser::TransformBegin},
        {"TransformEnd", &SceneParser::TransformEnd},
        {"TransformTimes", &SceneParser::TransformTimes},
        {"Translate", &SceneParser::Translate},
        {"WorldBegin", &SceneParser::WorldBegin},
    };
    if (t.kind != Token::Kind::kWord) Fail(t, "expected a directive, got " + t.Describe());
    auto it = kDirectives.find(t.word);
    if (it == kDirectives.end()) {
      std::string hint;
      if (t.word == "WorldEnd") hint = " (pbrt-v3 syntax: in pbrt-v4 the world ends with the file)";
      Fail(t, "unknown directive " + Quoted(Printable(t.word)) + hint);
    }
    (this->*(it->second))(t);
  }

  // Options block: rendering settings the builder interprets.
  TypedEntity ReadTypedEntity(const Token& t) {
    TypedEntity e;
    e.type = ExpectString(t, "a type name");
    e.params = ParseParams();
    e.loc = Loc(t);
    return e;
  }
  void Film(const Token& t) {
    VerifyOptions(t);
    scene_.film = ReadTypedEntity(t);
  }
  void PixelFilter(const Token& t) {
    VerifyOptions(t);
    scene_.filter = ReadTypedEntity(t);
  }
  void Sampler(const Token& t) {
    VerifyOptions(t);
    scene_.sampler = ReadTypedEntity(t);
  }
  void Integrator(const Token& t) {
    VerifyOptions(t);
    scene_.integrator = ReadTypedEntity(t);
  }
  void Accelerator(const Token& t) {
    VerifyOptions(t);
    scene_.accelerator = ReadTypedEntity(t);
  }

  void Camera(const Token& t) {
    VerifyOptions(t);
    TypedEntity e = ReadTypedEntity(t);
    std::optional<Transform> world_from_camera = gs_.ctm.Inverse();
    if (!world_from_camera) Fail(t, "the transform in force at Camera is singular");
    CameraDesc& c = scene_.camera;
    static_cast<TypedEntity&>(c) = std::move(e);
    c.camera_from_world = gs_.ctm;
    c.medium = UseMedia(t).second;
    scene_.has_camera = true;
    named_coordinate_systems_["camera"] = *world_from_camera;
  }

  void Option(const Token& t) {
    std::string name = ExpectString(t, "an option name");
    Token value = Expect(t, "an option value");
    // pbrt-v4 compares names case-insensitively and ignores '-' and '_'; the value may be
    // written with a type ("bool disablepixeljitter").
    if (size_t space = name.find_last_of(" \t"); space != std::string::npos)
      name = name.substr(space + 1);
    std::string key;
    for (char c : name)
      if (c != '-' && c != '_')
        key += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    std::string_view text =
        value.kind == Token::Kind::kString ? std::string_view(value.str) : value.word;

    // Hints that change how pbrt samples or reports, not what the image converges to.
    static const std::set<std::string_view> kIgnoredBool = {
        "disablepixeljitter", "disabletexturefiltering", "disablewavelengthjitter", "pixelstats",
        "wavefront"};
    static const std::set<std::string_view> kIgnoredOther = {
        "displacementedgescale", "msereferenceimage", "msereferenceout", "rendercoordsys", "seed"};
    if (kIgnoredBool.count(key) || key == "forcediffuse") {
      if (text != "true" && text != "false")
        Fail(value, "Option " + Quoted(Printable(name)) + " expects true or false, got " +
                        value.Describe());
      if (key == "forcediffuse" && text == "true")
        Fail(t, "Option \"forcediffuse\" is not supported (it changes every material)");
    } else if (!kIgnoredOther.count(key)) {
      Fail(t, "unknown Option " + Quoted(Printable(name)));
    }
  }

  void ColorSpace(const Token& t) {
    Token name = ExpectStringToken(t, "a color space name");
    // lightfarm renders in linear sRGB; another working space would need its own primaries.
    if (name.str != "srgb")
      Fail(name, "unsupported color space " + Quoted(Printable(name.str)) + " (only \"srgb\")");
  }

  void WorldBegin(const Token& t) {
    if (in_world_) Fail(t, "WorldBegin appears twice");
    if (!blocks_.empty())
      Fail(t, "WorldBegin inside " + BlockName(blocks_.back().kind) + " opened at " +
                  blocks_.back().loc.ToString());
    in_world_ = true;
    gs_.ctm = Transform();
    named_coordinate_systems_["world"] = gs_.ctm;
  }

  // Transforms. Each post-multiplies the CTM, as in pbrt: the last one written applies first.
  void Identity(const Token&) { gs_.ctm = Transform(); }
  void Translate(const Token& t) {
    double x = ExpectNumber(t), y = ExpectNumber(t), z = ExpectNumber(t);
    ConcatenateCTM(Transform::Translate(Vec3(float(x), float(y), float(z))));
  }
  void Scale(const Token& t) {
    double x = ExpectNumber(t), y = ExpectNumber(t), z = ExpectNumber(t);
    ConcatenateCTM(Transform::Scale(float(x), float(y), float(z)));
  }
  void Rotate(const Token& t) {
    double angle = ExpectNumber(t), x = ExpectNumber(t), y = ExpectNumber(t), z = ExpectNumber(t);
    if (x == 0 && y == 0 && z == 0) Fail(t, "Rotate axis is (0, 0, 0)");
    ConcatenateCTM(Transform::Rotate(float(angle), Vec3(float(x), float(y), float(z))));
  }
  void LookAt(const Token& t) {
    double v[9];
    for (double& x : v) x = ExpectNumber(t);
    std::optional<Transform> camera_from_world = Transform::LookAt(
        Vec3(float(v[0]), float(v[1]), float(v[2])), Vec3(float(v[3]), float(v[4]), float(v[5])),
        Vec3(float(v[6]), float(v[7]), float(v[8])));
    if (!camera_from_world)
      Fail(t, "LookAt is degenerate: eye equals look, or up is zero or parallel to the view");
    ConcatenateCTM(*camera_from_world);
  }
  void TransformDirective(const Token& t) { gs_.ctm = ReadMatrix(t); }
  void ConcatTransform(const Token& t) { ConcatenateCTM(ReadMatrix(t)); }

  void CoordinateSystem(const Token& t) {
    named_coordinate_systems_[ExpectString(t, "a coordinate system name")] = gs_.ctm;
  }
  void CoordSysTransform(const Token& t) {
    Token name = ExpectStringToken(t, "a coordinate system name");
    auto it = named_coordinate_systems_.find(name.str);
    if (it == named_coordinate_systems_.end())
      Fail(name, "unknown coordinate system " + Quoted(Printable(name.str)));
    gs_.ctm = it->second;
  }

  void ActiveTransform(const Token& t) {
    Token which = Expect(t, "All, StartTime or EndTime");
    if (which.IsWord("All")) return;
    if (which.IsWord("StartTime") || which.IsWord("EndTime"))
      Fail(t, "motion blur (ActiveTransform) is not supported");
    Fail(which, "ActiveTransform expects All, StartTime or EndTime, got " + which.Describe());
  }
  void TransformTimes(const Token& t) {
    double start = ExpectNumber(t), end = ExpectNumber(t);
    // pbrt-v4's defaults are 0 and 1; anything else only matters for motion blur.
    if (start != 0 || end != 1) Fail(t, "motion blur (TransformTimes) is not supported");
  }

  // Attribute and transform blocks.
  void AttributeBegin(const Token& t) {
    VerifyWorld(t);
    PushBlock(t, Block::Kind::kAttribute);
  }
  void AttributeEnd(const Token& t) {
    VerifyWorld(t);
    gs_ = PopBlock(t, Block::Kind::kAttribute).saved;
  }
  // Deprecated in pbrt-v4 (which treats them as AttributeBegin/End); here, as in pbrt-v3, they
  // save and restore only the CTM.
  void TransformBegin(const Token& t) { PushBlock(t, Block::Kind::kTransform); }
  void TransformEnd(const Token& t) { gs_.ctm = PopBlock(t, Block::Kind::kTransform).saved.ctm; }
  void ReverseOrientation(const Token& t) {
    VerifyWorld(t);
    gs_.reverse_orientation = !gs_.reverse_orientation;
  }

  void Attribute(const Token& t) {
    Token target = ExpectStringToken(t, "a target (shape, light, material, medium or texture)");
    ParamSet params = ParseParams();
    ParamSet* defaults = nullptr;
    if (target.str == "shape")
      defaults = &gs_.shape_defaults;
    else if (target.str == "light")
      defaults = &gs_.light_defaults;
    else if (target.str == "material")
      defaults = &gs_.material_defaults;
    else if (target.str == "medium")
      defaults = &gs_.medium_defaults;
    else if (target.str == "texture")
      defaults = &gs_.texture_defaults;
    else
      Fail(target, "unknown Attribute target " + Quoted(Printable(target.str)) +
                       " (expected shape, light, material, medium or texture)");
    for (const Param& p : params.params()) defaults->Add(p);
  }

  // Materials.
  void Material(const Token& t) {
    VerifyWorld(t);
    MaterialDesc m;
    static_cast<TypedEntity&>(m) = ReadTypedEntity(t);
    m.params.AddDefaults(gs_.material_defaults);
    RecordFileParam(m.params, "normalmap");
    gs_.material = static_cast<int>(scene_.materials.size());
    scene_.materials.push_back(std::move(m));
  }

  void MakeNamedMaterial(const Token& t) {
    VerifyWorld(t);
    Token name = ExpectStringToken(t, "a material name");
    ParamSet params = ParseParams();
    if (auto it = scene_.named_materials.find(name.str); it != scene_.named_materials.end())
      Fail(name, "named material " + Quoted(Printable(name.str)) + " redefined (first defined at " +
                     scene_.materials[it->second].loc.ToString() + ")");
    params.AddDefaults(gs_.material_defaults);
    MaterialDesc m;
    m.type = params.GetOneString("type", "");
    if (m.type.empty())
      Fail(t, "MakeNamedMaterial " + Quoted(Printable(name.str)) +
                  " has no \"string type\" parameter");
    m.params = WithoutType(params);
    m.loc = Loc(t);
    m.name = name.str;
    RecordFileParam(m.params, "normalmap");
    scene_.named_materials[name.str] = static_cast<int>(scene_.materials.size());
    scene_.materials.push_back(std::move(m));
  }

  void NamedMaterial(const Token& t) {
    VerifyWorld(t);
    Token name = ExpectStringToken(t, "a material name");
    auto it = scene_.named_materials.find(name.str);
    if (it == scene_.named_materials.end())
      Fail(name, "unknown named material " + Quoted(Printable(name.str)));
    gs_.material = it->second;
  }

  void Texture(const Token& t) {
    VerifyWorld(t);
    Token name = ExpectStringToken(t, "a texture name");
    Token value_type = ExpectStringToken(t, "a texture value type (float or spectrum)");
    TextureDesc tex;
    tex.type = ExpectString(t, "a texture class");
    tex.params = ParseParams();
    tex.loc = Loc(t);
    if (value_type.str != "float" && value_type.str != "spectrum")
      Fail(value_type, "texture value type must be \"float\" or \"spectrum\", got " +
                           Quoted(Printable(value_type.str)));
    // pbrt-v4 keeps float and spectrum textures in separate namespaces; SceneDescription has
    // one, so a name may only be used once.
    if (auto it = scene_.textures.find(name.str); it != scene_.textures.end())
      Fail(name, "texture " + Quoted(Printable(name.str)) + " redefined (first defined at " +
                     it->second.loc.ToString() + ")");
    tex.params.AddDefaults(gs_.texture_defaults);
    tex.name = name.str;
    tex.value_type = value_type.str;
    tex.world_from_texture = gs_.ctm;
    RecordFileParam(tex.params, "filename");
    scene_.textures[name.str] = std::move(tex);
  }

  // Media.
  void MakeNamedMedium(const Token& t) {
    Token name = ExpectStringToken(t, "a medium name");
    ParamSet params = ParseParams();
    if (auto it = scene_.media.find(name.str); it != scene_.media.end())
      Fail(name, "named medium " + Quoted(Printable(name.str)) + " redefined (first defined at " +
                     it->second.loc.ToString() + ")");
    params.AddDefaults(gs_.medium_defaults);
    MediumDesc m;
    m.type = params.GetOneString("type", "");
    if (m.type.empty())
      Fail(t,
           "MakeNamedMedium " + Quoted(Printable(name.str)) + " has no \"string type\" parameter");
    m.params = WithoutType(params);
    m.loc = Loc(t);
    m.name = name.str;
    m.world_from_medium = gs_.ctm;
    RecordFileParam(m.params, "filename");
    scene_.media[name.str] = std::move(m);
  }

  void MediumInterface(const Token& t) {
    MediumInterfaceUse mi;
    mi.loc = Loc(t);
    mi.inside = ExpectString(t, "an inside medium name");
    // The outside name is optional; one name means the same medium on both sides.
    std::optional<Token> second = NextToken();
    if (second && second->kind == Token::Kind::kString) {
      mi.outside = second->str;
    } else {
      if (second) Unget(std::move(*second));
      mi.outside = mi.inside;
    }
    if (mi.inside.empty() && mi.outside.empty()) {
      gs_.medium_interface = -1;
      return;
    }
    gs_.medium_interface = static_cast<int>(medium_interfaces_.size());
    medium_interfaces_.push_back(std::move(mi));
  }

  // Lights and shapes.
  void LightSource(const Token& t) {
    VerifyWorld(t);
    LightDesc light;
    static_cast<TypedEntity&>(light) = ReadTypedEntity(t);
    light.params.AddDefaults(gs_.light_defaults);
    light.world_from_light = gs_.ctm;
    light.medium = UseMedia(t).second;
    RecordFileParam(light.params, "filename");
    scene_.lights.push_back(std::move(light));
  }

  void AreaLightSource(const Token& t) {
    VerifyWorld(t);
    TypedEntity area = ReadTypedEntity(t);
    area.params.AddDefaults(gs_.light_defaults);
    RecordFileParam(area.params, "filename");
    gs_.area_light = std::move(area);
  }

  void Shape(const Token& t) {
    VerifyWorld(t);
    ShapeDesc s;
    static_cast<TypedEntity&>(s) = ReadTypedEntity(t);
    s.params.AddDefaults(gs_.shape_defaults);
    s.world_from_object = gs_.ctm;
    s.reverse_orientation = gs_.reverse_orientation;
    s.material = gs_.material;
    s.area_light = gs_.area_light;
    std::tie(s.inside_medium, s.outside_medium) = UseMedia(t);
    RecordFileParam(s.params, "filename");
    if (active_object_.empty()) {
      scene_.shapes.push_back(std::move(s));
      return;
    }
    // An instance is one BVH shared by all its uses; emitters must be individual objects.
    if (s.area_light)
      Fail(t, "AreaLightSource (from " + s.area_light->loc.ToString() +
                  ") cannot apply to a shape inside ObjectBegin: instanced area lights are not "
                  "supported");
    scene_.instance_definitions[active_object_].push_back(std::move(s));
  }

  // Object instancing.
  void ObjectBegin(const Token& t) {
    VerifyWorld(t);
    Token name = ExpectStringToken(t, "an object name");
    if (!active_object_.empty())
      Fail(t, "ObjectBegin " + Quoted(Printable(name.str)) + " inside ObjectBegin " +
                  Quoted(Printable(active_object_)) + " (opened at " +
                  active_object_loc_.ToString() + ")");
    if (scene_.instance_definitions.count(name.str))
      Fail(name, "object " + Quoted(Printable(name.str)) + " redefined");
    PushBlock(t, Block::Kind::kObject);
    active_object_ = name.str;
    active_object_loc_ = Loc(t);
    scene_.instance_definitions[name.str];  // an empty object is still a defined object
  }

  void ObjectEnd(const Token& t) {
    VerifyWorld(t);
    if (active_object_.empty()) Fail(t, "ObjectEnd without a matching ObjectBegin");
    gs_ = PopBlock(t, Block::Kind::kObject).saved;
    active_object_.clear();
  }

  void ObjectInstance(const Token& t) {
    VerifyWorld(t);
    Token name = ExpectStringToken(t, "an object name");
    if (!active_object_.empty())
      Fail(t, "ObjectInstance inside ObjectBegin " + Quoted(Printable(active_object_)) +
                  " (nested instancing is not supported)");
    // Checked in Finish(): pbrt-v4 allows an instance to be used before it is defined.
    scene_.instance_uses.push_back(InstanceUse{name.str, gs_.ctm, Loc(name)});
  }

  void Include(const Token& t) { OpenIncluded(t, false); }
  void Import(const Token& t) {
    VerifyWorld(t);
    OpenIncluded(t, true);
  }

  // --- End of input --------------------------------------------------------------------------

  void Finish() {
    if (!blocks_.empty())
      throw SceneError(blocks_.back().loc, BlockName(blocks_.back().kind) + " is never closed");
    if (!in_world_) throw SceneError(end_of_root_, "end of file before WorldBegin");
    for (const MediumInterfaceUse& mi : medium_interfaces_) {
      if (!mi.first_use) continue;
      for (const std::string* name : {&mi.inside, &mi.outside})
        if (!name->empty() && !scene_.media.count(*name))
          throw SceneError(mi.loc, "unknown medium " + Quoted(Printable(*name)) +
                                       " in MediumInterface (used at " + mi.first_use->ToString() +
                                       ")");
    }
    for (const InstanceUse& use : scene_.instance_uses)
      if (!scene_.instance_definitions.count(use.name))
        throw SceneError(use.loc,
                         "unknown object " + Quoted(Printable(use.name)) + " in ObjectInstance");
  }

  SceneDescription scene_;
  std::set<std::string> files_seen_;
  std::vector<OpenFile> files_;
  std::optional<Token> unget_;
  uintmax_t total_bytes_ = 0;
  int include_count_ = 0;
  FileLoc end_of_root_;

  GraphicsState gs_;
  std::vector<Block> blocks_;
  std::map<std::string, Transform> named_coordinate_systems_;
  std::vector<MediumInterfaceUse> medium_interfaces_;
  bool in_world_ = false;
  std::string active_object_;
  FileLoc active_object_loc_;
};

std::string CanonicalOrEmpty(const std::string& path) {
  std::error_code ec;
  std::string c = fs::weakly_canonical(path, ec).string();
  return ec ? std::string() : c;
}

}  // namespace

std::string SceneDescription::ResolvePath(const std::string& name) const {
  if (name.empty() || base_dir.empty() || fs::path(name).is_absolute()) return name;
  return (fs::path(base_dir) / name).lexically_normal().string();
}

SceneDescription ParseSceneFile(const std::string& path) {
  std::string contents = ReadFileContents(path, FileLoc{path, 0, 0}, "scene file");
  std::string base_dir = fs::path(path).parent_path().string();
  SceneParser parser(path, base_dir.empty() ? "." : base_dir);
  parser.AddFile(path);
  return parser.Parse(std::move(contents), CanonicalOrEmpty(path));
}

SceneDescription ParseSceneString(const std::string& text, const std::string& filename,
                                  const std::string& base_dir) {
  // No file was read for the root, so `files` starts with the first Include, if any.
  if (text.size() > kMaxFileBytes)
    throw SceneError(FileLoc{filename, 0, 0}, "scene text is larger than 1 GiB");
  SceneParser parser(filename, base_dir);
  return parser.Parse(text, "");
}

}  // namespace lightfarm
