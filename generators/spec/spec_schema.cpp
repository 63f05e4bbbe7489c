#include "generators/spec/spec_schema.hpp"
#include "generators/spec/spec_table.hpp"
#include "generators/spec/stage_params.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace chromasim::generators {
namespace detail {
namespace { // internal linkage: these names are common

// ---- Converting scalar text -----------------------------------------------------------------

/// `text` without one leading '+' (std::from_chars rejects it; YAML allows it).
std::string_view strip_plus(std::string_view text) {
    if (text.size() > 1 && text[0] == '+' && text[1] != '+' && text[1] != '-') {
        text.remove_prefix(1);
    }
    return text;
}

ScalarCheck check_number(const SchemaEntry& e, std::string_view text, bool quoted) {
    if (quoted) return {0.0, "is quoted text, not a number"};
    const std::string_view digits = strip_plus(text);
    double x = 0.0;
    const auto [end, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), x);
    if (ec == std::errc::result_out_of_range) return {0.0, "is out of range"};
    if (ec != std::errc{} || end != digits.data() + digits.size()) {
        return {0.0, "is not a number"};
    }
    if (!std::isfinite(x)) return {0.0, "is not a finite number"};
    if (!e.range.contains(x)) return {x, "is out of range"};
    return {x, ""};
}

ScalarCheck check_integer(const SchemaEntry& e, std::string_view text, bool quoted) {
    if (quoted) return {std::int64_t{0}, "is quoted text, not an integer"};
    const std::string_view digits = strip_plus(text);
    std::int64_t n = 0;
    const auto [end, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), n);
    if (ec == std::errc::result_out_of_range) return {n, "is out of range"};
    if (ec != std::errc{} || end != digits.data() + digits.size()) {
        return {n, "is not an integer"};
    }
    if (!e.range.contains(static_cast<double>(n))) return {n, "is out of range"};
    return {n, ""};
}

ScalarCheck check_bool(std::string_view text, bool quoted) {
    if (quoted) return {false, "is quoted text, not true or false"};
    if (text == "true") return {true, ""};
    if (text == "false") return {false, ""};
    return {false, "is not true or false"};
}

ScalarCheck check_enum(const SchemaEntry& e, std::string_view text) {
    const std::string value(text);
    if (std::find(e.choices.begin(), e.choices.end(), value) != e.choices.end()) {
        return {value, ""};
    }
    for (const auto& [old_name, new_name] : e.renamed)
        if (value == old_name)
            return {value, "is now called '" + new_name + "' (the same choice, renamed)"};
    const std::string near = closest_match(text, e.choices);
    return {value, near.empty()
                       ? "is not one of the allowed values"
                       : "is not one of the allowed values (did you mean '" + near + "'?)"};
}

// ---- Formatting -----------------------------------------------------------------------------

/// Shortest round-trip text of `x`, as std::to_chars writes it ("35", "0.8", "1e-07").
std::string shortest(double x) {
    char buf[64];
    const auto [end, ec] = std::to_chars(buf, buf + sizeof buf, x);
    (void)ec; // 64 chars always suffice for a double
    return std::string(buf, end);
}

/// A bound of a range: integers for integer entries, shortest text otherwise.
std::string format_bound(ValueType type, double x) {
    if (type == ValueType::Integer) return std::to_string(static_cast<std::int64_t>(x));
    return shortest(x);
}

std::string range_text(const SchemaEntry& e) {
    return std::string(e.range.lo_inclusive ? "[" : "(") + format_bound(e.type, e.range.lo) + ", " +
           format_bound(e.type, e.range.hi) + (e.range.hi_inclusive ? "]" : ")");
}

std::string join(const std::vector<std::string>& items, const std::string& sep,
                 const std::string& quote = "") {
    std::string out;
    for (std::size_t i = 0; i < items.size(); ++i) {
        out += (i ? sep : "") + quote + items[i] + quote;
    }
    return out;
}

/// A YAML double-quoted scalar; escapes are the JSON-compatible subset of YAML.
std::string quote_yaml(const std::string& s) {
    std::string out = "\"";
    for (const char c : s) {
        const auto u = static_cast<unsigned char>(c);
        if (c == '"' || c == '\\') {
            out += '\\';
            out += c;
        } else if (u < 0x20 || u == 0x7f) {
            char buf[8];
            std::snprintf(buf, sizeof buf, "\\x%02x", u);
            out += buf;
        } else {
            out += c;
        }
    }
    return out + "\"";
}

std::vector<std::string> split_key(const std::string& key) {
    std::vector<std::string> parts;
    std::size_t start = 0;
    for (std::size_t dot = key.find('.'); dot != std::string::npos; dot = key.find('.', start)) {
        parts.push_back(key.substr(start, dot - start));
        start = dot + 1;
    }
    parts.push_back(key.substr(start));
    return parts;
}

const char* type_name(ValueType type) {
    switch (type) {
    case ValueType::Number:
        return "number";
    case ValueType::Integer:
        return "integer";
    case ValueType::Bool:
        return "bool";
    case ValueType::Enum:
        return "enum";
    case ValueType::String:
        return "string";
    case ValueType::Rgb:
        return "rgb";
    case ValueType::Vec3:
        return "vec3";
    case ValueType::Factor:
        return "factor";
    case ValueType::Varied:
        return "varied";
    case ValueType::Numbers:
        return "numbers";
    }
    return "?";
}

// ---- The manual -----------------------------------------------------------------------------

/// The "allowed" column: the range, the words, or the shape.
std::string allowed_cell(const SchemaEntry& e) {
    switch (e.type) {
    case ValueType::Number:
    case ValueType::Integer:
        return range_text(e);
    case ValueType::Bool:
        return "`true`, `false`";
    case ValueType::Enum:
        return join(e.choices, ", ", "`");
    case ValueType::String:
        return std::get<std::string>(e.default_value).empty() ? "text (may be empty)" : "non-empty";
    case ValueType::Rgb:
    case ValueType::Vec3:
        return "3 numbers, each in " + range_text(e);
    case ValueType::Factor:
    case ValueType::Varied:
        return "number, list of numbers or {min, max}, each in " + range_text(e);
    case ValueType::Numbers:
        return "number or list of numbers, each in " + range_text(e);
    }
    return "";
}

std::string markdown_cell(std::string s) {
    std::string out;
    for (const char c : s) {
        out += (c == '|') ? std::string("\\|") : std::string(1, c);
    }
    return out;
}

const char* markdown_intro() {
    return R"(# Spec reference

A dataset spec is a YAML file: one mapping whose keys nest by the dots of the keys below
(`sensor.led.count: 6` is written `sensor:` / `  led:` / `    count: 6`). Every key is optional
and takes its default when left out; a section written with nothing under it (`sensor:`) keeps
all its defaults. `datasets_spec/quickstart.yaml` is a commented example that shows every
section.

Reading rules (an error names the file, line:column, key, value and what is allowed):
- An unknown key is an error, with a "did you mean" suggestion when a known key is close.
- `number`: decimal or exponent notation (`0.5`, `-1`, `2e-3`), finite. `integer`: decimal
  digits only (`2.5`, `2.0` and `1e3` are rejected).
- `bool`: exactly `true` or `false` (`yes`, `no`, `on`, `off`, `True` are rejected).
- Quoted text (`"1.5"`) is a string: it is never taken as a number or a bool. A quoted value
  ends on the line it starts.
- Files the spec names (object meshes, spectra) are read while it is checked, so `validate`
  refuses what `generate` would; a rule between keys points at its key, or at the section
  above it when the key is left out.
- `rgb`: a list of exactly 3 numbers in red, green, blue order, e.g. `[0.85, 0.85, 0.85]`.
- `vec3`: a list of exactly 3 numbers x, y, z, e.g. `[0.0, 0.0, -1.5]`.
- `factor`: a factor of the sampling plan: one number (`1.5`), a non-empty list of numbers
  (`[1.0, 1.5, 2.0]`) or a uniform range (`{min: 2, max: 3}`, both keys, min <= max); every
  number in the allowed range. How trials draw from it: `sampling.method`.
- `varied`: a sensor value, written as one number; or as a list or a range (as a factor)
  to randomize the sensor: each of `sampling.sensor_variants` sensors draws every varied key
  once (a list item or a uniform value), every trial uses one of them, and `sensors.csv`
  records which and its values (docs/DATASET_FORMAT.md).
- Lists of mappings: `objects`, `friction` and `splits` are YAML lists whose items are
  mappings with the keys written `objects[].KEY` below, e.g.
  `objects: [{name: flat, shape: flat}, {name: curved, shape: sphere, radius_mm: 45}]`. A
  list has at least one item; a list left out is the one-item list of the item defaults.
  Errors name the item as `objects[1].radius_mm` (items count from 0).
- Ranges: `[a, b]` includes both ends, `(a, b]` excludes `a`.
- A key given twice in the same mapping is an error.
- [G] marks an assumption: a default to override when better data exist.

This file is generated from the schema table in `generators/spec/spec_table.cpp`; regenerate it with
`chromasim spec-doc > docs/SPEC.md`. A test (`tests/generators/test_spec.cpp`) fails
when it no longer matches the schema.

| key | type | default | unit | allowed | doc |
|---|---|---|---|---|---|
)";
}

} // namespace
} // namespace detail

// ---- Public functions -----------------------------------------------------------------------

bool Range::contains(double x) const {
    const bool above_lo = lo_inclusive ? x >= lo : x > lo;
    const bool below_hi = hi_inclusive ? x <= hi : x < hi;
    return above_lo && below_hi;
}

const std::vector<SchemaEntry>& spec_schema() {
    static const std::vector<SchemaEntry> schema = detail::build_schema();
    return schema;
}

std::string SchemaEntry::list() const {
    const std::size_t brackets = key.find("[].");
    return brackets == std::string::npos ? std::string() : key.substr(0, brackets);
}

const std::vector<SchemaList>& spec_lists() {
    static const std::vector<SchemaList> lists = detail::build_lists();
    return lists;
}

const SchemaList* find_schema_list(std::string_view name) {
    for (const SchemaList& l : spec_lists())
        if (l.name == name) return &l;
    return nullptr;
}

const std::vector<SchemaRule>& spec_rules() {
    static const std::vector<SchemaRule> rules = detail::build_rules();
    return rules;
}

const SchemaEntry* find_schema_entry(std::string_view key) {
    for (const SchemaEntry& e : spec_schema()) {
        if (e.key == key) return &e;
    }
    return nullptr;
}

void set_varied_value(Spec& spec, const std::string& key, double value) {
    const SchemaEntry* entry = find_schema_entry(key);
    if (!entry || entry->type != ValueType::Varied)
        throw std::logic_error("set_varied_value: '" + key + "' is not a varied key");
    entry->set(spec, 0, Factor{std::vector<double>{value}});
}

bool is_schema_section(std::string_view key) {
    if (key.empty()) return true;
    for (const SchemaEntry& e : spec_schema()) {
        if (e.key.size() > key.size() && e.key.compare(0, key.size(), key) == 0 &&
            e.key[key.size()] == '.') {
            return true;
        }
    }
    return false;
}

std::vector<std::string> schema_children(std::string_view section) {
    const std::string prefix = section.empty() ? "" : std::string(section) + ".";
    std::vector<std::string> names;
    for (const SchemaEntry& e : spec_schema()) {
        if (e.key.compare(0, prefix.size(), prefix) != 0) continue;
        const std::string rest = e.key.substr(prefix.size());
        std::string name = rest.substr(0, rest.find('.'));
        if (name.size() > 2 && name.compare(name.size() - 2, 2, "[]") == 0)
            name.resize(name.size() - 2);
        if (std::find(names.begin(), names.end(), name) == names.end()) names.push_back(name);
    }
    return names;
}

ScalarCheck check_scalar(const SchemaEntry& entry, std::string_view text, bool quoted) {
    switch (entry.type) {
    case ValueType::Number:
    case ValueType::Rgb:
    case ValueType::Vec3:
    case ValueType::Factor:
    case ValueType::Varied:
    case ValueType::Numbers:
        return detail::check_number(entry, text, quoted);
    case ValueType::Integer:
        return detail::check_integer(entry, text, quoted);
    case ValueType::Bool:
        return detail::check_bool(text, quoted);
    case ValueType::Enum:
        return detail::check_enum(entry, text);
    case ValueType::String:
        // Text whose default is empty may stay empty (an optional path); other text may not.
        if (text.empty() && !std::get<std::string>(entry.default_value).empty())
            return {std::string(), "is empty"};
        return {std::string(text), ""};
    }
    return {0.0, "has an unknown type"};
}

std::string describe_allowed(const SchemaEntry& entry) {
    const std::string unit = entry.unit.empty() ? "" : " (" + entry.unit + ")";
    switch (entry.type) {
    case ValueType::Number:
        return "number in " + detail::range_text(entry) + unit;
    case ValueType::Integer:
        return "integer in " + detail::range_text(entry) + unit;
    case ValueType::Bool:
        return "true or false";
    case ValueType::Enum:
        return "one of " + detail::join(entry.choices, ", ");
    case ValueType::String:
        return std::get<std::string>(entry.default_value).empty() ? "text (may be empty)"
                                                                  : "non-empty string";
    case ValueType::Rgb:
    case ValueType::Vec3:
        return "list of 3 numbers, each in " + detail::range_text(entry) + unit;
    case ValueType::Factor:
        return "a number, a non-empty list of numbers, or {min, max} with min <= max, each in " +
               detail::range_text(entry) + unit;
    case ValueType::Varied:
        return "number in " + detail::range_text(entry) + unit +
               ", or a list or {min, max} of them (a varied sensor)";
    case ValueType::Numbers:
        return "a number or a non-empty list of numbers, each in " + detail::range_text(entry) +
               unit;
    }
    return "";
}

double lowest(const Factor& f) {
    return f.is_range ? f.min : *std::min_element(f.values.begin(), f.values.end());
}

double highest(const Factor& f) {
    return f.is_range ? f.max : *std::max_element(f.values.begin(), f.values.end());
}

std::string format_number(double x) {
    std::string s = detail::shortest(x);
    if (s.find_first_not_of("-0123456789") == std::string::npos) s += ".0";
    return s;
}

std::string value_to_yaml(const SpecValue& value, ValueType type) {
    switch (type) {
    case ValueType::Number:
        return format_number(std::get<double>(value));
    case ValueType::Integer:
        return std::to_string(std::get<std::int64_t>(value));
    case ValueType::Bool:
        return std::get<bool>(value) ? "true" : "false";
    case ValueType::Enum:
        return std::get<std::string>(value);
    case ValueType::String:
        return detail::quote_yaml(std::get<std::string>(value));
    case ValueType::Rgb:
    case ValueType::Vec3: {
        const Rgb& c = std::get<Rgb>(value);
        return "[" + format_number(c[0]) + ", " + format_number(c[1]) + ", " + format_number(c[2]) +
               "]";
    }
    case ValueType::Factor:
    case ValueType::Varied:
    case ValueType::Numbers: {
        const Factor& f = std::get<Factor>(value);
        // A sensor value that does not vary, or one number for all, reads as the plain number.
        if (type != ValueType::Factor && !f.is_range && f.values.size() == 1)
            return format_number(f.values[0]);
        if (f.is_range)
            return "{min: " + format_number(f.min) + ", max: " + format_number(f.max) + "}";
        std::string out = "[";
        for (std::size_t i = 0; i < f.values.size(); ++i)
            out += (i ? ", " : "") + format_number(f.values[i]);
        return out + "]";
    }
    }
    return "";
}

std::string resolved_spec_yaml(const Spec& spec) {
    std::string out = "# chromasim resolved spec: every key, defaults filled, schema order.\n";
    std::vector<std::string> open; // the sections the previous key was in
    const auto& schema = spec_schema();
    for (std::size_t k = 0; k < schema.size(); ++k) {
        const SchemaEntry& e = schema[k];
        if (const std::string list = e.list(); !list.empty()) {
            // A list (its entries are contiguous): every item, its keys in schema order.
            std::size_t end = k;
            while (end < schema.size() && schema[end].list() == list)
                ++end;
            out += list + ":\n";
            for (std::size_t i = 0; i < find_schema_list(list)->size(spec); ++i)
                for (std::size_t j = k; j < end; ++j)
                    out += std::string(j == k ? "  - " : "    ") +
                           schema[j].key.substr(list.size() + 3) + ": " +
                           value_to_yaml(schema[j].get(spec, i), schema[j].type) + "\n";
            open.clear();
            k = end - 1;
            continue;
        }
        std::vector<std::string> parts = detail::split_key(e.key);
        const std::string leaf = parts.back();
        parts.pop_back();
        std::size_t common = 0;
        while (common < open.size() && common < parts.size() && open[common] == parts[common]) {
            ++common;
        }
        for (std::size_t i = common; i < parts.size(); ++i) {
            out += std::string(2 * i, ' ') + parts[i] + ":\n";
        }
        out += std::string(2 * parts.size(), ' ') + leaf + ": " +
               value_to_yaml(e.get(spec, 0), e.type) + "\n";
        open = std::move(parts);
    }
    return out;
}

Spec default_spec() {
    Spec spec;
    for (const SchemaList& list : spec_lists())
        list.resize(spec, 1);
    for (const SchemaEntry& e : spec_schema()) {
        e.set(spec, 0, e.default_value);
    }
    return spec;
}

std::size_t edit_distance(std::string_view a, std::string_view b) {
    // d[i][j]: distance between the first i chars of a and the first j chars of b.
    std::vector<std::vector<std::size_t>> d(a.size() + 1, std::vector<std::size_t>(b.size() + 1));
    for (std::size_t i = 0; i <= a.size(); ++i) {
        d[i][0] = i;
    }
    for (std::size_t j = 0; j <= b.size(); ++j) {
        d[0][j] = j;
    }
    for (std::size_t i = 1; i <= a.size(); ++i) {
        for (std::size_t j = 1; j <= b.size(); ++j) {
            const std::size_t cost = a[i - 1] == b[j - 1] ? 0 : 1;
            d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + cost});
            if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1]) {
                d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
            }
        }
    }
    return d[a.size()][b.size()];
}

std::string closest_match(std::string_view word, const std::vector<std::string>& candidates,
                          std::size_t max_distance) {
    std::string best;
    std::size_t best_distance = max_distance + 1;
    for (const std::string& c : candidates) {
        const std::size_t d = edit_distance(word, c);
        // A distance equal to the longer length means nothing in common: no suggestion.
        if (d < best_distance && d < std::max(word.size(), c.size())) {
            best = c;
            best_distance = d;
        }
    }
    return best;
}

std::string schema_markdown() {
    std::string out = detail::markdown_intro();
    for (const SchemaEntry& e : spec_schema()) {
        out += "| `" + e.key + "` | " + detail::type_name(e.type) + " | `" +
               detail::markdown_cell(value_to_yaml(e.default_value, e.type)) + "` | " +
               detail::markdown_cell(e.unit) + " | " +
               detail::markdown_cell(detail::allowed_cell(e)) + " | " +
               detail::markdown_cell(e.doc) + " |\n";
    }
    out += "\nLists of mappings:\n";
    for (const SchemaList& l : spec_lists())
        out += "- `" + l.name + "`: " + l.doc + "\n";
    out += "\nCross-key rules, checked once every key is valid:\n";
    for (const SchemaRule& r : spec_rules()) {
        out += "- `" + r.key + "`: " + r.allowed + ".\n";
    }
    out += "\nQuality presets: the fast integrator's extra samples that `render.quality` sets (a "
           "count at most `render.samples_per_pixel` adds none):\n\n" +
           quality_presets_markdown();
    return out;
}

} // namespace chromasim::generators
