#pragma once
/// @file
/// Strict YAML configuration: load a plain config struct from YAML and save it back.
///
/// A config struct describes its keys once, in a `Serialize` member template; the same
/// function drives loading, saving and the list of allowed keys, so `LoadString(SaveString(x))`
/// gives back `x` (Drake's YAML archives, Cartographer's "every key used exactly once"):
///
/// ```
/// struct ClockConfig {
///   double rate_hz = 50.0;            // defaults live in the declaration
///   std::string mode = "wall";
///   std::optional<int> seed;
///   std::chrono::nanoseconds timeout_s = std::chrono::seconds(2);
///
///   template <typename Archive>
///   void Serialize(Archive& a) {
///     a.Optional("rate_hz", rate_hz, config::Range{0.01, 100.0});
///     a.Optional("mode", mode, config::OneOf{{"wall", "sim"}});
///     a.Required("seed", seed);       // must be present; may be `null`
///     a.Optional("timeout_s", timeout_s);
///   }
///   void Validate() const;            // optional: cross-field rules, throws ConfigError
/// };
/// const auto clock = config::LoadFile<ClockConfig>("city.yaml", "clock");
/// const std::string text = config::SaveString(clock);
/// ```
///
/// Rules:
/// - `a.Optional(key, field, validators...)`: the key may be absent, and then the field keeps
///   the value it had (the default from its initialiser). `a.Required(key, field,
///   validators...)`: an absent key is an error. A present key is read completely; nothing is
///   merged except that a nested struct or an engaged `std::optional` struct starts from its
///   current value, so its own optional keys keep their defaults.
/// - A mapping read as a struct may hold only the keys its `Serialize` names, each once.
/// - Supported field types: `bool` (only `true` and `false`; YAML 1.1's yes/no/on/off are
///   rejected), every integer type except the character types (decimal only, range-checked
///   against the C++ type), `float` and `double` (decimal or exponent notation, integers
///   accepted; `.inf`, `-.inf`, `.nan` only with `AllowNonFinite`), `std::string`, enums with a
///   name table (see `ConfigEnumNames` below), `std::chrono::nanoseconds` written as a number of
///   seconds (put the unit in the key: `yellow_s: 3.0`; rounded to the nearest nanosecond, half
///   away from zero), `std::optional<T>` (absent or `null` is `std::nullopt`),
///   `std::vector<T>`, `std::map<std::string, T>`, and structs with `Serialize`, nested to any
///   depth, and types with `FromConfigString`/`ToConfigString` written as one string (see
///   `StringConvertible`). Numbers and booleans must be plain YAML scalars: `"3"` is a string, not
///   a number.
/// - Enums: declare, in the enum's namespace (found by argument-dependent lookup),
///   `constexpr auto ConfigEnumNames(MyEnum) { return std::array{std::pair{MyEnum::kA,
///   std::string_view{"a"}}, ...}; }`: any range of pairs (enumerator, name).
/// - Validators (`Range`, `OneOf`, `AllowNonFinite`) apply to every scalar inside the field:
///   to the value of an engaged optional and to each element of a vector or map. `Predicate`
///   applies to the field's whole value as declared.
/// - After a struct is read its `void Validate() const`, if it has one, is called; an
///   `InputError` (or `ConfigError`) thrown from it is rethrown as a `ConfigError` with the
///   struct's location in front.
///
/// Errors: every problem in the YAML throws `autodrive::ConfigError` whose message is
/// `FILE:LINE:COLUMN: KEYPATH: what was wrong (got ...; expected ...)`, with 1-based line and
/// column and KEYPATH like `intersections[2].timing.yellow_s` (`<root>` for the document
/// itself, `plans["rush hour"]` for a map key that is not an identifier). The kinds:
/// `unknown key (did you mean rate_hz? allowed keys: rate_hz, mode)`, `missing required key`
/// (at the enclosing mapping), `duplicate key (first defined at line 2, column 1)`, `wrong type
/// (got a mapping; expected a finite number)`, `out of range (got 300; expected an integer in
/// [0, 255])`, `not an allowed value (got "wal"; expected one of "wall", "sim")`, `invalid
/// value (got 3; expected <the Predicate's description>)`, and a `Validate()` message after the
/// struct's KEYPATH. Two kinds have no key: a YAML syntax error is `FILE:LINE:COLUMN: YAML
/// syntax error (yaml-cpp's message)` and a file that cannot be read is `FILE: cannot read file
/// (reason)`. Unknown and duplicate keys are reported before missing ones, so a misspelt
/// required key is named as the typo.
///
/// Saved YAML is block style in declaration order, every key written (`null` for an empty
/// optional), lists of scalars in flow style (`gains: [1.0, 2.5]`), numbers in the shortest
/// text that reads back exactly, strings quoted unless they are plain words.
///
/// Nothing here keeps state between calls; all functions may be called from any thread.
///
/// Strings saved must be valid UTF-8 without Unicode noncharacters (U+FDD0..U+FDEF,
/// U+xFFFE, U+xFFFF), which yaml-cpp does not round-trip; saving one throws `ConfigError`.

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <chrono>
#include <concepts>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <type_traits>
#include <utility>
#include <vector>

#include "common/error.h"

namespace autodrive::config {

/// Validator: the value must lie in the closed interval [min, max]. Works for integers,
/// floating-point numbers (bounds of any arithmetic type) and durations (bounds are
/// `std::chrono` durations: `Range<std::chrono::nanoseconds>{100ms, 5s}`). Precondition:
/// `min <= max`.
template <typename T>
struct Range {
  T min;  ///< Smallest allowed value, inclusive.
  T max;  ///< Largest allowed value, inclusive.
};
/// Deduces `Range{0.01, 100.0}` as `Range<double>`.
template <typename T>
Range(T, T) -> Range<T>;

/// Validator for strings: the value must be one of `allowed`, e.g. `OneOf{{"wall", "sim"}}`.
struct OneOf {
  std::vector<std::string> allowed;  ///< The allowed strings, in the order messages list them.
};

/// Validator: `test(field)` must return true; `description` says what is expected and is
/// printed in the error, e.g. `Predicate{"an even number", [](int v) { return v % 2 == 0; }}`.
/// The predicate receives the field's whole value (for a vector field, the vector).
template <typename F>
struct Predicate {
  std::string description;  ///< What a valid value is, as a noun phrase ("an even number").
  F test;                   ///< Callable `bool(const FieldType&)`.
};
/// Deduces `Predicate{"text", lambda}`.
template <typename F>
Predicate(std::string, F) -> Predicate<F>;

/// Validator for `float` and `double` fields: also accept `.inf`, `-.inf` and `.nan`.
struct AllowNonFinite {};

/// A field that holds a section belonging to another program, carried without being read: any
/// YAML value, kept as its YAML text. A city file's `sim:` section is one for the SCM; the
/// simulator reads it with `LoadFile<SimConfig>(path, "sim")`. Equal when the texts are.
struct ForeignSection {
  std::string yaml;  ///< The value as YAML text (yaml-cpp's dump of it).
  bool operator==(const ForeignSection&) const = default;
};

/// The bytes of a file (a city file, a log a test reads back); throws ConfigError
/// "PATH: cannot read file (reason)".
[[nodiscard]] std::string ReadFile(const std::filesystem::path& path);
/// Writes a file whole; throws ConfigError "PATH: cannot write file (reason)".
void WriteFile(const std::filesystem::path& path, std::string_view text);

namespace internal {

class KeyLister;

/// Where a YAML value is, for error messages.
struct Loc {
  const std::string* file;  ///< File (or string) name; never null.
  YAML::Mark mark;          ///< Position in the file, 0-based (yaml-cpp's convention).
  std::string path;         ///< Key path, e.g. `intersections[2].timing`; empty for the root.
};

/// Throws `ConfigError` with "FILE:LINE:COLUMN: KEYPATH: message".
[[noreturn]] void Fail(const Loc& loc, std::string_view message);
/// `path.key`, or `path["key"]` when the key is not a plain identifier.
[[nodiscard]] std::string JoinKey(std::string_view path, std::string_view key);
/// `path[index]`.
[[nodiscard]] std::string JoinIndex(std::string_view path, std::size_t index);
/// What a node is, for "got ..." in messages: `a mapping`, `null`, `1.5`, `the string "x"`.
[[nodiscard]] std::string Describe(const YAML::Node& node);
/// A string in double quotes with escapes, shortened if long.
[[nodiscard]] std::string Quote(std::string_view text);
/// The YAML text of `node` in one canonical form (block style throughout), so that a
/// `ForeignSection` reads back equal from the text it was saved as.
[[nodiscard]] std::string DumpSection(const YAML::Node& node);

/// A key's value in a mapping, and where to report problems with it.
struct Entry {
  YAML::Node value;  ///< The value node.
  YAML::Mark mark;   ///< The value's mark, or the key's when the value is an empty null.
};
/// Throws unless `node` is a mapping whose keys are non-null scalars, each present once, and
/// (when `allowed` is not null) each one of `allowed`.
void CheckMappingKeys(const YAML::Node& node, const Loc& loc,
                      const std::vector<std::string>* allowed);
/// The value of `key` in the mapping `map`, or nullopt. Precondition: `map` is a mapping.
[[nodiscard]] std::optional<Entry> FindKey(const YAML::Node& map, std::string_view key);
/// Every (key, entry) of a mapping, in document order. Precondition: keys were checked.
[[nodiscard]] std::vector<std::pair<std::string, Entry>> Entries(const YAML::Node& map);
/// Throws unless `node` is a sequence.
void ExpectSequence(const YAML::Node& node, const Loc& loc);

// Scalar parsers: each throws ConfigError with the right message on bad input.
[[nodiscard]] bool ParseBool(const YAML::Node& node, const Loc& loc);
[[nodiscard]] std::int64_t ParseSigned(const YAML::Node& node, const Loc& loc, std::int64_t min,
                                       std::int64_t max);
[[nodiscard]] std::uint64_t ParseUnsigned(const YAML::Node& node, const Loc& loc,
                                          std::uint64_t max);
[[nodiscard]] double ParseDouble(const YAML::Node& node, const Loc& loc, bool allow_non_finite);
[[nodiscard]] float ParseFloat(const YAML::Node& node, const Loc& loc, bool allow_non_finite);
[[nodiscard]] std::string ParseString(const YAML::Node& node, const Loc& loc);
[[nodiscard]] std::chrono::nanoseconds ParseDuration(const YAML::Node& node, const Loc& loc);
/// The index of the node's text in `names`; throws listing `names` otherwise.
[[nodiscard]] std::size_t ParseName(const YAML::Node& node, const Loc& loc,
                                    const std::vector<std::string_view>& names);
/// Throws "not an allowed value" unless `value` is one of `one_of.allowed`.
void CheckOneOf(const Loc& loc, const std::string& value, const OneOf& one_of);

// Formatting of numbers: shortest text that reads back exactly (".0" added to integral values).
[[nodiscard]] std::string FormatDouble(double value);
[[nodiscard]] std::string FormatFloat(float value);
/// Exact decimal seconds of a nanosecond count: 1500000000 -> "1.5".
[[nodiscard]] std::string FormatSeconds(std::int64_t ns);

// Emitting.
/// Writes a string scalar: plain when that is unambiguous, double-quoted otherwise. Throws
/// ConfigError naming `path` when the string is not valid UTF-8 or holds a noncharacter.
void WriteString(YAML::Emitter& out, std::string_view path, std::string_view text);
/// Writes a scalar whose text needs no quoting (numbers, true/false, null).
void WritePlain(YAML::Emitter& out, const std::string& text);
/// Configures an emitter: block style, 2-space indent, `null` for null.
void ConfigureEmitter(YAML::Emitter& out);
/// The emitted text with a final newline; aborts if the emitter reports an error (a bug).
[[nodiscard]] std::string FinishEmitter(const YAML::Emitter& out);

// Documents.
/// A parsed document and the node to read the config struct from.
struct Document {
  std::string file;  ///< Name used in messages.
  YAML::Node root;   ///< The node to read (the whole document or the value of `key`).
  YAML::Mark mark;   ///< Where `root` is.
  std::string path;  ///< Key path of `root` (empty or `key`).
};
/// Parses exactly one YAML document; with a non-empty `key`, selects that top-level key
/// (missing is an error; other top-level keys are allowed). Throws ConfigError.
[[nodiscard]] Document ParseDocument(const std::string& yaml, std::string name,
                                     std::string_view key);

// Type traits.
template <typename T>
inline constexpr bool kAlwaysFalse = false;
template <typename T>
struct IsOptional : std::false_type {};
template <typename T>
struct IsOptional<std::optional<T>> : std::true_type {};
template <typename T>
struct IsVector : std::false_type {};
template <typename T>
struct IsVector<std::vector<T>> : std::true_type {};
template <typename T>
struct IsStringMap : std::false_type {};
template <typename T>
struct IsStringMap<std::map<std::string, T>> : std::true_type {};
template <typename T>
struct IsRange : std::false_type {};
template <typename T>
struct IsRange<Range<T>> : std::true_type {};
template <typename T>
struct IsPredicate : std::false_type {};
template <typename F>
struct IsPredicate<Predicate<F>> : std::true_type {};
template <typename T>
struct IsChronoDuration : std::false_type {};
template <typename R, typename P>
struct IsChronoDuration<std::chrono::duration<R, P>> : std::true_type {};

/// Integer types read as numbers (not bool, not the character types).
template <typename T>
concept Integer = std::integral<T> && !std::same_as<T, bool> && !std::same_as<T, char> &&
                  !std::same_as<T, wchar_t> && !std::same_as<T, char8_t> &&
                  !std::same_as<T, char16_t> && !std::same_as<T, char32_t>;

/// Enums with a `ConfigEnumNames(E)` name table found by argument-dependent lookup.
template <typename E>
concept NamedEnum = std::is_enum_v<E> && requires(E e) {
  ConfigEnumNames(e);
};

/// Types written as one string in YAML: they provide `static T FromConfigString(std::string_view)`
/// (throwing `InputError` on bad text) and `std::string ToConfigString() const`.
template <typename T>
concept StringConvertible = requires(const T& t, std::string_view s) {
  { T::FromConfigString(s) } -> std::same_as<T>;
  { t.ToConfigString() } -> std::convertible_to<std::string>;
};

/// Types written as one YAML scalar (or null), which vectors of them list in flow style.
template <typename T>
struct IsScalar : std::bool_constant<std::is_arithmetic_v<T> || std::is_same_v<T, std::string> ||
                                     std::is_same_v<T, std::chrono::nanoseconds> ||
                                     std::is_enum_v<T> || StringConvertible<T>> {};
template <typename T>
struct IsScalar<std::optional<T>> : IsScalar<T> {};

/// Types that can have a `Validate() const` hook.
template <typename T>
concept HasValidate = requires(const T& t) {
  t.Validate();
};

}  // namespace internal

/// A config struct: it has `template <typename Archive> void Serialize(Archive& a)` that calls
/// `a.Optional(key, field, validators...)` / `a.Required(...)` once per key.
template <typename T>
concept Serializable = std::is_class_v<T> && requires(T& t, internal::KeyLister& a) {
  t.Serialize(a);
};

namespace internal {

template <typename T, typename... V>
void ReadValue(const YAML::Node& node, const Loc& loc, T& value, const V&... validators);
template <typename T>
void ReadStruct(const YAML::Node& node, const Loc& loc, T& value);
template <typename T>
void WriteValue(YAML::Emitter& out, const std::string& path, const T& value);

/// The archive that only records the key names a `Serialize` visits, in order.
class KeyLister {
 public:
  /// Records `key`.
  template <typename T, typename... V>
  void Optional(std::string_view key, T& /*value*/, const V&... /*validators*/) {
    Add(key);
  }
  /// Records `key`.
  template <typename T, typename... V>
  void Required(std::string_view key, T& /*value*/, const V&... /*validators*/) {
    Add(key);
  }
  /// The keys, in visiting order.
  [[nodiscard]] const std::vector<std::string>& keys() const { return keys_; }

 private:
  void Add(std::string_view key) {
    AUTODRIVE_CHECK(std::find(keys_.begin(), keys_.end(), key) == keys_.end(),
                    "Serialize visits key '" << key << "' twice");
    keys_.emplace_back(key);
  }
  std::vector<std::string> keys_;
};

/// Checks a `Predicate` against a field's whole value (the other validators are checked on
/// every scalar by `ReadValue`).
template <typename T, typename V>
void CheckWhole([[maybe_unused]] const YAML::Node& node, [[maybe_unused]] const Loc& loc,
                [[maybe_unused]] const T& value, [[maybe_unused]] const V& validator) {
  if constexpr (IsPredicate<V>::value) {
    if (!static_cast<bool>(validator.test(value))) {
      Fail(loc,
           "invalid value (got " + Describe(node) + "; expected " + validator.description + ")");
    }
  }
}

/// The archive that reads a struct's fields from a YAML mapping.
class Reader {
 public:
  /// Reads from `map`, a mapping whose keys were checked; `loc` is where the mapping is.
  Reader(const YAML::Node& map, const Loc& loc) : map_(map), loc_(loc) {}

  /// Reads `key` into `value` if present; keeps `value` otherwise.
  template <typename T, typename... V>
  void Optional(std::string_view key, T& value, const V&... validators) {
    Visit(key, value, /*required=*/false, validators...);
  }
  /// Reads `key` into `value`; throws if absent.
  template <typename T, typename... V>
  void Required(std::string_view key, T& value, const V&... validators) {
    Visit(key, value, /*required=*/true, validators...);
  }

 private:
  template <typename T, typename... V>
  void Visit(std::string_view key, T& value, bool required, const V&... validators) {
    const std::optional<Entry> entry = FindKey(map_, key);
    if (!entry) {
      if (required)
        Fail(Loc{loc_.file, loc_.mark, JoinKey(loc_.path, key)}, "missing required key");
      return;
    }
    const Loc loc{loc_.file, entry->mark, JoinKey(loc_.path, key)};
    ReadValue(entry->value, loc, value, validators...);
    (CheckWhole(entry->value, loc, value, validators), ...);
  }

  const YAML::Node& map_;
  const Loc& loc_;
};

/// The archive that writes a struct's fields as YAML key/value pairs.
class Writer {
 public:
  /// Writes into `out`, which is inside a mapping; `path` is the struct's key path.
  Writer(YAML::Emitter& out, std::string path) : out_(out), path_(std::move(path)) {}
  /// Writes `key: value`.
  template <typename T, typename... V>
  void Optional(std::string_view key, const T& value, const V&... /*validators*/) {
    Write(key, value);
  }
  /// Writes `key: value`.
  template <typename T, typename... V>
  void Required(std::string_view key, const T& value, const V&... /*validators*/) {
    Write(key, value);
  }

 private:
  template <typename T>
  void Write(std::string_view key, const T& value) {
    const std::string path = JoinKey(path_, key);
    out_ << YAML::Key;
    WriteString(out_, path, key);
    out_ << YAML::Value;
    WriteValue(out_, path, value);
  }

  YAML::Emitter& out_;
  std::string path_;
};

/// Checks one validator against a scalar `value` read from `node`.
template <typename T, typename V>
void CheckLeaf(const YAML::Node& node, const Loc& loc, const T& value, const V& validator) {
  if constexpr (IsRange<V>::value) {
    using R = std::remove_cvref_t<decltype(validator.min)>;
    AUTODRIVE_CHECK(!(validator.max < validator.min), "Range with min > max at " << loc.path);
    bool inside = false;
    std::string min_text;
    std::string max_text;
    if constexpr (Integer<T> && Integer<R>) {
      inside =
          std::cmp_greater_equal(value, validator.min) && std::cmp_less_equal(value, validator.max);
      min_text = std::to_string(validator.min);
      max_text = std::to_string(validator.max);
    } else if constexpr (IsChronoDuration<T>::value) {
      static_assert(IsChronoDuration<R>::value, "a Range on a duration needs duration bounds");
      inside = value >= validator.min && value <= validator.max;
      min_text = FormatSeconds(
          std::chrono::duration_cast<std::chrono::nanoseconds>(validator.min).count());
      max_text = FormatSeconds(
          std::chrono::duration_cast<std::chrono::nanoseconds>(validator.max).count());
    } else {
      static_assert(
          (Integer<T> || std::is_floating_point_v<T>)&&(Integer<R> || std::is_floating_point_v<R>),
          "Range applies to numbers and durations only");
      const auto v = static_cast<long double>(value);
      inside = v >= static_cast<long double>(validator.min) &&
               v <= static_cast<long double>(validator.max);
      if constexpr (Integer<R>) {
        min_text = std::to_string(validator.min);
        max_text = std::to_string(validator.max);
      } else {
        min_text = FormatDouble(static_cast<double>(validator.min));
        max_text = FormatDouble(static_cast<double>(validator.max));
      }
    }
    if (!inside) {
      Fail(loc, "out of range (got " + Describe(node) + "; expected a value in [" + min_text +
                    ", " + max_text + "])");
    }
  } else if constexpr (std::is_same_v<V, OneOf>) {
    static_assert(std::is_same_v<T, std::string>, "OneOf applies to strings only");
    CheckOneOf(loc, value, validator);
  } else if constexpr (std::is_same_v<V, AllowNonFinite>) {
    static_assert(std::is_floating_point_v<T>, "AllowNonFinite applies to float and double only");
  } else if constexpr (IsPredicate<V>::value) {
    // Checked on the whole field by Reader::Visit.
  } else {
    static_assert(kAlwaysFalse<V>,
                  "unknown validator: use Range, OneOf, Predicate or "
                  "AllowNonFinite");
  }
}

/// Reads a scalar of a supported type.
template <typename T, typename... V>
void ReadLeaf(const YAML::Node& node, const Loc& loc, T& value) {
  constexpr bool kAllowNonFinite = (std::is_same_v<V, AllowNonFinite> || ...);
  if constexpr (std::is_same_v<T, bool>) {
    value = ParseBool(node, loc);
  } else if constexpr (Integer<T> && std::is_signed_v<T>) {
    value = static_cast<T>(
        ParseSigned(node, loc, std::numeric_limits<T>::min(), std::numeric_limits<T>::max()));
  } else if constexpr (Integer<T>) {
    value = static_cast<T>(ParseUnsigned(node, loc, std::numeric_limits<T>::max()));
  } else if constexpr (std::is_same_v<T, double>) {
    value = ParseDouble(node, loc, kAllowNonFinite);
  } else if constexpr (std::is_same_v<T, float>) {
    value = ParseFloat(node, loc, kAllowNonFinite);
  } else if constexpr (std::is_same_v<T, std::string>) {
    value = ParseString(node, loc);
  } else if constexpr (std::is_same_v<T, std::chrono::nanoseconds>) {
    value = ParseDuration(node, loc);
  } else if constexpr (NamedEnum<T>) {
    std::vector<std::string_view> names;
    std::vector<T> enumerators;
    for (const auto& [enumerator, name] : ConfigEnumNames(T{})) {
      enumerators.push_back(enumerator);
      names.emplace_back(name);
    }
    value = enumerators[ParseName(node, loc, names)];
  } else if constexpr (StringConvertible<T>) {
    const std::string text = ParseString(node, loc);
    try {
      value = T::FromConfigString(text);
    } catch (const InputError& e) {
      Fail(loc, e.what());
    }
  } else {
    static_assert(kAlwaysFalse<T>,
                  "autodrive::config cannot read this type: use bool, an integer, float, "
                  "double, std::string, std::chrono::nanoseconds, an enum with "
                  "ConfigEnumNames, std::optional, std::vector, std::map<std::string, T> or "
                  "a struct with Serialize");
  }
}

/// Reads `node` into `value`, recursing through optionals, vectors, maps and structs, and
/// applies the scalar validators to every scalar read.
template <typename T, typename... V>
void ReadValue(const YAML::Node& node, const Loc& loc, T& value, const V&... validators) {
  if constexpr (std::is_same_v<T, ForeignSection>) {
    value.yaml = DumpSection(node);
  } else if constexpr (IsOptional<T>::value) {
    if (node.IsNull()) {
      value.reset();
      return;
    }
    if (!value) value.emplace();
    ReadValue(node, loc, *value, validators...);
  } else if constexpr (IsVector<T>::value) {
    ExpectSequence(node, loc);
    T result;
    result.reserve(node.size());
    std::size_t index = 0;
    for (const auto& item : node) {
      typename T::value_type element{};
      ReadValue(YAML::Node(item), Loc{loc.file, item.Mark(), JoinIndex(loc.path, index)}, element,
                validators...);
      result.push_back(std::move(element));
      ++index;
    }
    value = std::move(result);
  } else if constexpr (IsStringMap<T>::value) {
    CheckMappingKeys(node, loc, /*allowed=*/nullptr);
    T result;
    for (const auto& [key, entry] : Entries(node)) {
      typename T::mapped_type element{};
      ReadValue(entry.value, Loc{loc.file, entry.mark, JoinKey(loc.path, key)}, element,
                validators...);
      result.emplace(key, std::move(element));
    }
    value = std::move(result);
  } else if constexpr (Serializable<T>) {
    static_assert((IsPredicate<V>::value && ...),
                  "only Predicate validators apply to a struct; use its Validate() instead");
    ReadStruct(node, loc, value);
  } else {
    ReadLeaf<T, V...>(node, loc, value);
    (CheckLeaf(node, loc, value, validators), ...);
  }
}

/// Reads a struct from a mapping: checks the keys, reads every field, calls `Validate()`.
template <typename T>
void ReadStruct(const YAML::Node& node, const Loc& loc, T& value) {
  KeyLister lister;
  value.Serialize(lister);
  CheckMappingKeys(node, loc, &lister.keys());
  Reader reader(node, loc);
  value.Serialize(reader);
  if constexpr (HasValidate<T>) {
    try {
      value.Validate();
    } catch (const InputError& e) {
      Fail(loc, e.what());
    }
  }
}

/// Writes `value` of any supported type.
template <typename T>
void WriteValue(YAML::Emitter& out, const std::string& path, const T& value) {
  if constexpr (std::is_same_v<T, ForeignSection>) {
    out << YAML::Load(value.yaml);
  } else if constexpr (IsOptional<T>::value) {
    if (value) {
      WriteValue(out, path, *value);
    } else {
      out << YAML::Null;
    }
  } else if constexpr (IsVector<T>::value) {
    // `key: [1.0, 2.0]` for scalars, and `key: []` rather than `[]` on its own line.
    if (value.empty() || IsScalar<typename T::value_type>::value) out << YAML::Flow;
    out << YAML::BeginSeq;
    std::size_t index = 0;
    for (const auto& element : value) {
      WriteValue(out, JoinIndex(path, index++),
                 static_cast<const typename T::value_type&>(element));
    }
    out << YAML::EndSeq;
  } else if constexpr (IsStringMap<T>::value) {
    if (value.empty()) out << YAML::Flow;  // `key: {}`
    out << YAML::BeginMap;
    for (const auto& [key, element] : value) {
      const std::string element_path = JoinKey(path, key);
      out << YAML::Key;
      WriteString(out, element_path, key);
      out << YAML::Value;
      WriteValue(out, element_path, element);
    }
    out << YAML::EndMap;
  } else if constexpr (Serializable<T>) {
    out << YAML::BeginMap;
    Writer writer(out, path);
    // Serialize is non-const because the same function also loads; the Writer only reads.
    const_cast<T&>(value).Serialize(writer);
    out << YAML::EndMap;
  } else if constexpr (std::is_same_v<T, bool>) {
    WritePlain(out, value ? "true" : "false");
  } else if constexpr (Integer<T>) {
    WritePlain(out, std::to_string(value));
  } else if constexpr (std::is_same_v<T, double>) {
    WritePlain(out, FormatDouble(value));
  } else if constexpr (std::is_same_v<T, float>) {
    WritePlain(out, FormatFloat(value));
  } else if constexpr (std::is_same_v<T, std::string>) {
    WriteString(out, path, value);
  } else if constexpr (std::is_same_v<T, std::chrono::nanoseconds>) {
    WritePlain(out, FormatSeconds(value.count()));
  } else if constexpr (NamedEnum<T>) {
    for (const auto& [enumerator, name] : ConfigEnumNames(T{})) {
      if (enumerator == value) {
        WriteString(out, path, name);
        return;
      }
    }
    AUTODRIVE_CHECK(false, "enum value " << static_cast<long long>(value) << " at " << path
                                         << " is missing from its ConfigEnumNames table");
  } else if constexpr (StringConvertible<T>) {
    WriteString(out, path, value.ToConfigString());
  } else {
    static_assert(kAlwaysFalse<T>, "autodrive::config cannot write this type");
  }
}

}  // namespace internal

/// Loads a `T` from YAML text. `name` stands for the file name in error messages. With an
/// empty `key` the whole document is the struct; otherwise the document must be a mapping and
/// its top-level `key` is the struct (other top-level keys are ignored, `key` is required).
/// Fields absent from optional keys keep `T{}`'s defaults; `Validate()` hooks run.
/// Throws `ConfigError` (see the file comment for the message form).
template <Serializable T>
[[nodiscard]] T LoadString(const std::string& yaml, std::string name = "<string>",
                           std::string_view key = {}) {
  const internal::Document document = internal::ParseDocument(yaml, std::move(name), key);
  T value{};
  internal::ReadStruct(document.root, internal::Loc{&document.file, document.mark, document.path},
                       value);
  return value;
}

/// Loads a `T` from the YAML file at `path`; `key` as for `LoadString`. Throws `ConfigError`
/// if the file cannot be read (message names the path) or its contents are bad.
template <Serializable T>
[[nodiscard]] T LoadFile(const std::filesystem::path& path, std::string_view key = {}) {
  return LoadString<T>(ReadFile(path), path.string(), key);
}

/// The YAML text of `value`: a block mapping with the keys in declaration order, every key
/// written (`null` for an empty optional), numbers in the shortest form that reads back
/// exactly. `LoadString<T>(SaveString(x)) == x` for every value that passes its validators.
/// Throws `ConfigError` if a string is not valid UTF-8 (see the file comment).
template <Serializable T>
[[nodiscard]] std::string SaveString(const T& value) {
  YAML::Emitter out;
  internal::ConfigureEmitter(out);
  internal::WriteValue(out, "", value);
  return internal::FinishEmitter(out);
}

/// Writes `SaveString(value)` to the file at `path`, replacing it. Throws `ConfigError` if the
/// file cannot be written (message names the path) or as `SaveString`.
template <Serializable T>
void SaveFile(const T& value, const std::filesystem::path& path) {
  WriteFile(path, SaveString(value));
}

}  // namespace autodrive::config
