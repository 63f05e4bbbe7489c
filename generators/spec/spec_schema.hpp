#pragma once
/// The spec schema: one entry per leaf key of a spec file, with its type, default, unit, allowed
/// values and doc line, and how it is read from and written to the typed `Spec`. The table is the
/// user manual (`schema_markdown()`); the YAML reader (spec_yaml.cpp) validates against it and
/// knows nothing of individual keys. Knows nothing of YAML itself either.
#include "generators/spec/spec.hpp"

#include <cstdint>
#include <functional>
#include <string>
#include <string_view>
#include <variant>
#include <utility>
#include <vector>

namespace chromasim::generators {

/// The kind of value a schema entry holds.
enum class ValueType {
    Number,  ///< finite double, range-checked
    Integer, ///< decimal integer, range-checked
    Bool,    ///< exactly `true` or `false`
    Enum,    ///< one of a fixed list of words
    String,  ///< any non-empty text
    Rgb,     ///< a list of exactly 3 numbers, each range-checked
    Vec3,    ///< a list of exactly 3 numbers (x, y, z of a point), each range-checked
    Factor,  ///< a sampling factor: a number, a list of numbers or {min, max}, range-checked
    /// A sensor value that may vary: a number, or a list or {min, max} drawn once per sensor
    /// variant (sampling.sensor_variants); read and stored as a Factor.
    Varied,
    /// One number, or a non-empty list of numbers (one per item, e.g. per LED), each
    /// range-checked; read and stored as a Factor's values.
    Numbers,
};

/// A validated value; the alternative matches the entry's ValueType (Number -> double,
/// Integer -> int64_t, Bool -> bool, Enum and String -> string, Rgb and Vec3 -> Rgb, the
/// std::array<double, 3> both are stored in, Factor, Varied and Numbers -> Factor).
using SpecValue = std::variant<double, std::int64_t, bool, std::string, Rgb, Factor>;

/// An interval of allowed numbers; each end is inclusive ("[") or exclusive ("(").
struct Range {
    double lo = 0.0;
    double hi = 0.0;
    bool lo_inclusive = true;
    bool hi_inclusive = true;

    /// Whether `x` lies in the interval.
    bool contains(double x) const;
};

/// One leaf key of the spec. A key inside a list of mappings (objects, friction, splits) is
/// written with "[]" after the list's name, e.g. "objects[].radius_mm": it exists once per
/// item, and `set`/`get` take the item's index (ignored by keys outside lists).
struct SchemaEntry {
    std::string key; ///< dotted path, e.g. "sensor.materials.coating.E_MPa", "objects[].shape"
    ValueType type = ValueType::Number;
    SpecValue default_value;
    std::string unit;                 ///< e.g. "MPa", "deg"; empty when unitless
    Range range;                      ///< Number, Integer, each Rgb/Vec3 item
    std::vector<std::string> choices; ///< Enum only
    /// Enum only: retired values and the choice that replaced each (refused with its name).
    std::vector<std::pair<std::string, std::string>> renamed;
    std::string doc;                  ///< one line for the manual
    /// Stores a value of the right type (in item `item` of its list, if in one).
    std::function<void(Spec&, std::size_t item, const SpecValue&)> set;
    /// Reads the field back (of item `item` of its list, if in one).
    std::function<SpecValue(const Spec&, std::size_t item)> get;
    /// The list it belongs to ("objects" for "objects[].shape"); empty outside lists.
    std::string list() const;
};

/// A list of mappings in the spec (`objects`, `friction`, `splits`): its items' keys are the
/// schema entries "NAME[].KEY". Written as a YAML list of mappings; at least one item.
struct SchemaList {
    std::string name; ///< e.g. "objects"
    std::string doc;  ///< one line for the manual
    std::function<std::size_t(const Spec&)> size;
    /// Resizes the list; new items hold the item defaults.
    std::function<void(Spec&, std::size_t)> resize;
};

/// A constraint between keys, checked after every key is valid. A rule whose key lies in a list
/// ("objects[].mesh_file") is checked for every item and points at the failing one.
struct SchemaRule {
    std::string key; ///< the section or key that an error points at
    std::function<bool(const Spec&, std::size_t item)> holds;
    std::string problem; ///< e.g. "enables no output"
    std::string allowed; ///< what would be accepted
    /// Checks that a file the spec names exists: skipped for a spec read back from a dataset
    /// (parse_stored_spec), which reads none of them.
    bool reads_files = false;
    /// When set, replaces `holds` and `problem`: what is wrong with item `item` (empty: it
    /// holds), for rules whose problem is a file's own error.
    std::function<std::string(const Spec&, std::size_t item)> diagnose;
};

/// Outcome of converting one scalar's text for an entry: `problem` is empty when `value` holds
/// an allowed value, else it says what is wrong ("is not a number", "is out of range").
struct ScalarCheck {
    SpecValue value;
    std::string problem;
};

/// The schema, in manual order; sections are contiguous.
const std::vector<SchemaEntry>& spec_schema();

/// The cross-key rules, in the order they are checked.
const std::vector<SchemaRule>& spec_rules();

/// The lists of mappings, in manual order.
const std::vector<SchemaList>& spec_lists();

/// The list named `name` ("objects"), or nullptr.
const SchemaList* find_schema_list(std::string_view name);

/// The entry with this dotted key, or nullptr.
const SchemaEntry* find_schema_entry(std::string_view key);

/// Sets the `varied` key `key` to the one value `value` (no longer varied). Throws
/// std::logic_error if `key` is not a varied key.
void set_varied_value(Spec& spec, const std::string& key, double value);

/// Whether `key` is a section (a proper prefix of some entry's key, at a dot). "" is the top.
bool is_schema_section(std::string_view key);

/// The names of the keys directly inside `section` ("" is the top level, "objects[]" an item of
/// a list), in schema order, e.g. {"mesh_level", "materials", ...} for "sensor"; a list is
/// named without its "[]".
std::vector<std::string> schema_children(std::string_view section);

/// Converts and checks the text of one scalar for `entry` (for an Rgb entry or a Factor: one
/// number).
/// `quoted` is true when the text was written in quotes: quoted text is a string, never a
/// number or bool.
ScalarCheck check_scalar(const SchemaEntry& entry, std::string_view text, bool quoted);

/// What `entry` accepts, for error messages, e.g. "number in (0, 1000] (MPa)".
std::string describe_allowed(const SchemaEntry& entry);

/// The value as YAML text as the resolved spec writes it: numbers round-trip exactly, strings
/// are double-quoted, rgb is a flow list.
std::string value_to_yaml(const SpecValue& value, ValueType type);

/// Shortest text that reads back to exactly `x` (std::to_chars), with ".0" added to whole
/// numbers so they read as numbers, e.g. "0.8", "35.0", "1e-07".
std::string format_number(double x);

/// The spec with every schema key (schema order, nested by the dots, 2-space indent) and
/// nothing else. Deterministic: equal specs give byte-identical text.
std::string resolved_spec_yaml(const Spec& spec);

/// A spec holding every schema default (name, seed, ...); source_path and resolved_yaml empty.
Spec default_spec();

/// Optimal-string-alignment edit distance (insert, delete, substitute, swap neighbours).
std::size_t edit_distance(std::string_view a, std::string_view b);

/// The candidate closest to `word` within `max_distance` edits (first in order on ties), or "".
std::string closest_match(std::string_view word, const std::vector<std::string>& candidates,
                          std::size_t max_distance = 2);

} // namespace chromasim::generators
