// The YAML side of the spec: the only file that includes yaml-cpp. It checks the shape of the
// document (mappings, lists, scalars, known keys) and where each value sits in the file; the
// schema (spec_schema.cpp) converts and range-checks the values and fills the Spec.
#include "generators/spec/spec.hpp"
#include "generators/spec/spec_schema.hpp"

#include <yaml-cpp/eventhandler.h>
#include <yaml-cpp/yaml.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <map>
#include <sstream>
#include <set>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace chromasim::generators {
namespace detail {
namespace { // internal linkage: these names are common

/// A value read for an entry, in item `item` of its list (0 outside lists).
struct ReadValue {
    const SchemaEntry* entry = nullptr;
    std::size_t item = 0;
    SpecValue value;
};

/// Where a mapping sits: its schema section ("objects[]") and how messages name it
/// ("objects[1]"), and its item in its list.
struct Place {
    std::string section, display;
    std::size_t item = 0;
};

/// What one read of a spec text collects.
struct SpecReader {
    std::string file;                              ///< name used in messages
    std::vector<ReadValue> values;                 ///< in file order
    std::map<std::string, YAML::Mark> key_marks;   ///< every dotted key met, as messages name it
    std::map<std::string, std::size_t> list_sizes; ///< items of every list given
};

/// "FILE:LINE:COL" with yaml-cpp's 0-based mark printed 1-based; "FILE" when there is no mark.
std::string where(const std::string& file, const YAML::Mark& mark) {
    if (mark.is_null()) return file;
    return file + ":" + std::to_string(mark.line + 1) + ":" + std::to_string(mark.column + 1);
}

[[noreturn]] void fail(const SpecReader& r, const YAML::Mark& mark, const std::string& key,
                       const std::string& value, const std::string& problem,
                       const std::string& allowed) {
    throw SpecError(where(r.file, mark) + ": " + key + ": value '" + value + "' " + problem +
                    "; allowed: " + allowed);
}

std::string join(const std::vector<std::string>& items) {
    std::string out;
    for (std::size_t i = 0; i < items.size(); ++i) {
        out += (i ? ", " : "") + items[i];
    }
    return out;
}

/// "a mapping", "a list", ... for "value 'x' is a mapping, not a number".
std::string kind(const YAML::Node& node) {
    if (node.IsMap()) return "a mapping";
    if (node.IsSequence()) return "a list";
    if (node.IsNull()) return "empty";
    return "a single value";
}

/// The node as the user might have written it, on one line, cut at 60 characters.
std::string node_text(const YAML::Node& node) {
    if (node.IsScalar()) return node.Scalar();
    if (node.IsNull()) return "";
    YAML::Emitter out;
    out.SetMapFormat(YAML::Flow);
    out.SetSeqFormat(YAML::Flow);
    out << node;
    std::string text = out.c_str();
    if (text.size() > 60) text = text.substr(0, 57) + "...";
    return text;
}

/// Quoted scalars ('x', "x") and explicit !!str are text, never numbers or bools.
bool is_quoted(const YAML::Node& node) {
    return node.Tag() == "!" || node.Tag() == "tag:yaml.org,2002:str";
}

/// An empty value has no useful mark of its own (yaml-cpp points past it): use its key's.
YAML::Mark value_mark(const YAML::Node& key_node, const YAML::Node& value) {
    return value.IsNull() ? key_node.Mark() : value.Mark();
}

std::string keys_allowed_in(const std::string& section) {
    if (section.size() > 2 && section.compare(section.size() - 2, 2, "[]") == 0)
        return "keys in an item of '" + section.substr(0, section.size() - 2) +
               "': " + join(schema_children(section));
    return (section.empty() ? std::string("keys at the top level: ")
                            : "keys in '" + section + "': ") +
           join(schema_children(section));
}

/// The text of one scalar element, checked for `entry`; `key` names it in messages.
SpecValue read_scalar(const SpecReader& r, const SchemaEntry& entry, const std::string& key,
                      const YAML::Node& key_node, const YAML::Node& value) {
    const std::string allowed = describe_allowed(entry);
    if (value.IsNull()) fail(r, value_mark(key_node, value), key, "", "is empty", allowed);
    if (!value.IsScalar()) {
        fail(r, value.Mark(), key, node_text(value), "is " + kind(value) + ", not a single value",
             allowed);
    }
    const ScalarCheck check = check_scalar(entry, value.Scalar(), is_quoted(value));
    if (!check.problem.empty()) {
        fail(r, value.Mark(), key, value.Scalar(), check.problem, allowed);
    }
    return check.value;
}

SpecValue read_rgb(const SpecReader& r, const SchemaEntry& entry, const std::string& key,
                   const YAML::Node& key_node, const YAML::Node& value) {
    const std::string allowed = describe_allowed(entry);
    if (value.IsNull()) fail(r, value_mark(key_node, value), key, "", "is empty", allowed);
    if (!value.IsSequence()) {
        fail(r, value.Mark(), key, node_text(value), "is " + kind(value) + ", not a list", allowed);
    }
    if (value.size() != 3) {
        fail(r, value.Mark(), key, node_text(value),
             "has " + std::to_string(value.size()) + " items", allowed);
    }
    Rgb rgb{};
    for (std::size_t i = 0; i < 3; ++i) {
        const std::string item = key + "[" + std::to_string(i) + "]";
        rgb[i] = std::get<double>(read_scalar(r, entry, item, value, value[i]));
    }
    return rgb;
}

/// A factor: one number, a non-empty list of numbers, or a mapping {min, max}.
SpecValue read_factor(const SpecReader& r, const SchemaEntry& entry, const std::string& key,
                      const YAML::Node& key_node, const YAML::Node& value) {
    const std::string allowed = describe_allowed(entry);
    Factor f;
    if (value.IsScalar() || value.IsNull()) {
        f.values.push_back(std::get<double>(read_scalar(r, entry, key, key_node, value)));
        return f;
    }
    if (value.IsSequence()) {
        if (value.size() == 0) fail(r, value.Mark(), key, "[]", "is an empty list", allowed);
        for (std::size_t i = 0; i < value.size(); ++i)
            f.values.push_back(std::get<double>(
                read_scalar(r, entry, key + "[" + std::to_string(i) + "]", value, value[i])));
        return f;
    }
    if (entry.type == ValueType::Numbers)
        fail(r, value.Mark(), key, node_text(value), "is " + kind(value) + ", not a list", allowed);
    f.is_range = true;
    bool has_min = false, has_max = false;
    for (const auto& pair : value) {
        const std::string name = pair.first.IsScalar() ? pair.first.Scalar() : "";
        if (name != "min" && name != "max")
            fail(r, pair.first.Mark(), key + "." + node_text(pair.first), node_text(pair.first),
                 "is not a key of a range", allowed);
        bool& seen = name == "min" ? has_min : has_max;
        if (seen) fail(r, pair.first.Mark(), key + "." + name, name, "is given twice", allowed);
        seen = true;
        (name == "min" ? f.min : f.max) =
            std::get<double>(read_scalar(r, entry, key + "." + name, pair.first, pair.second));
    }
    if (!has_min || !has_max)
        fail(r, value.Mark(), key, node_text(value),
             std::string("has no ") + (has_min ? "max" : "min"), allowed);
    if (f.min > f.max) fail(r, value.Mark(), key, node_text(value), "has min above max", allowed);
    return f;
}

void read_map(SpecReader& r, const YAML::Node& map, const Place& place);

/// The place of key `name` inside `place`.
Place inside(const Place& place, const std::string& name) {
    return {place.section.empty() ? name : place.section + "." + name,
            place.display.empty() ? name : place.display + "." + name, place.item};
}

/// A section's value: a mapping, or empty (all defaults).
void read_section(SpecReader& r, const Place& place, const YAML::Node& value) {
    if (value.IsMap()) return read_map(r, value, place);
    if (value.IsNull()) return;
    fail(r, value.Mark(), place.display, node_text(value), "is " + kind(value) + ", not a mapping",
         "a mapping with " + keys_allowed_in(place.section));
}

/// A list of mappings (objects, friction, splits): at least one item, each a mapping.
void read_list(SpecReader& r, const std::string& name, const YAML::Node& key_node,
               const YAML::Node& value) {
    const std::string allowed =
        "a non-empty list of mappings with keys " + join(schema_children(name + "[]"));
    if (value.IsNull()) fail(r, value_mark(key_node, value), name, "", "is empty", allowed);
    if (!value.IsSequence())
        fail(r, value.Mark(), name, node_text(value), "is " + kind(value) + ", not a list",
             allowed);
    if (value.size() == 0) fail(r, value.Mark(), name, "[]", "is an empty list", allowed);
    r.list_sizes[name] = value.size();
    for (std::size_t i = 0; i < value.size(); ++i) {
        const Place item{name + "[]", name + "[" + std::to_string(i) + "]", i};
        r.key_marks.emplace(item.display, value[i].Mark());
        if (!value[i].IsMap())
            fail(r, value[i].Mark(), item.display, node_text(value[i]),
                 "is " + kind(value[i]) + ", not a mapping", allowed);
        read_map(r, value[i], item);
    }
}

/// render.fast keys that render.quality replaced; a spec that still has one is told so.
bool is_retired_fast_key(const std::string& name) {
    static const std::set<std::string> retired{
        "direct_samples",        "smoothing_mm",          "refresh_direct",
        "scale_indirect",        "shadow_filter_rim_px",  "reflection_samples_per_pixel",
        "edge_samples_per_pixel", "reflected_led_samples_per_pixel",
        "shadow_rays_per_pixel", "wavelengths_per_sample"};
    return retired.count(name) > 0;
}

[[noreturn]] void unknown_key(const SpecReader& r, const YAML::Node& key_node,
                              const std::string& key, const std::string& name,
                              const std::string& section) {
    const std::string near = closest_match(name, schema_children(section));
    std::string hint = near.empty() ? "" : " (did you mean '" + near + "'?)";
    if (name.find('.') != std::string::npos) {
        hint = " (a dotted key is written nested: one mapping per dot)";
    }
    if (section == "render.fast" && is_retired_fast_key(name)) {
        hint = " (render.quality sets it now: draft, default or high; docs/SPEC.md lists what "
               "each sets)";
    }
    throw SpecError(where(r.file, key_node.Mark()) + ": " + key + ": unknown key '" + name + "'" +
                    hint + "; allowed " + keys_allowed_in(section));
}

/// The key's name within its mapping; rejects keys that are not plain text.
std::string key_name(const SpecReader& r, const YAML::Node& key_node, const Place& place) {
    if (key_node.IsScalar()) return key_node.Scalar();
    fail(r, key_node.Mark(), place.display.empty() ? "(top level)" : place.display,
         node_text(key_node), "is not a valid key (" + kind(key_node) + ")",
         keys_allowed_in(place.section));
}

SpecValue read_value(const SpecReader& r, const SchemaEntry& entry, const std::string& key,
                     const YAML::Node& key_node, const YAML::Node& value) {
    switch (entry.type) {
    case ValueType::Rgb:
    case ValueType::Vec3:
        return read_rgb(r, entry, key, key_node, value);
    case ValueType::Factor:
    case ValueType::Varied:
    case ValueType::Numbers:
        return read_factor(r, entry, key, key_node, value);
    default:
        return read_scalar(r, entry, key, key_node, value);
    }
}

void read_entry(SpecReader& r, const Place& place, const YAML::Node& key_node,
                const YAML::Node& value) {
    const std::string name = key_name(r, key_node, place);
    const Place here = inside(place, name);
    const auto [first, inserted] = r.key_marks.emplace(here.display, key_node.Mark());
    if (!inserted) {
        fail(r, key_node.Mark(), here.display, name,
             "is given twice (first at line " + std::to_string(first->second.line + 1) + ")",
             "each key once per mapping");
    }
    if (!name.empty() && name.find('.') == std::string::npos) {
        if (const SchemaEntry* entry = find_schema_entry(here.section)) {
            r.values.push_back(
                {entry, place.item, read_value(r, *entry, here.display, key_node, value)});
            return;
        }
        if (place.section.empty() && find_schema_list(name))
            return read_list(r, name, key_node, value);
        if (is_schema_section(here.section)) return read_section(r, here, value);
    }
    unknown_key(r, key_node, here.display, name, place.section);
}

void read_map(SpecReader& r, const YAML::Node& map, const Place& place) {
    for (const auto& pair : map) {
        read_entry(r, place, pair.first, pair.second);
    }
}

/// Where the first documents of a text start, and where each one's first node is, from
/// yaml-cpp's event parser.
class DocumentMarks : public YAML::EventHandler {
public:
    std::vector<YAML::Mark> starts, nodes;

    void OnDocumentStart(const YAML::Mark& mark) override { starts.push_back(mark); }
    void OnDocumentEnd() override {}
    void OnNull(const YAML::Mark& mark, YAML::anchor_t) override { node(mark); }
    void OnAlias(const YAML::Mark& mark, YAML::anchor_t) override { node(mark); }
    void OnScalar(const YAML::Mark& mark, const std::string&, YAML::anchor_t,
                  const std::string&) override {
        node(mark);
    }
    void OnSequenceStart(const YAML::Mark& mark, const std::string&, YAML::anchor_t,
                         YAML::EmitterStyle::value) override {
        node(mark);
    }
    void OnSequenceEnd() override {}
    void OnMapStart(const YAML::Mark& mark, const std::string&, YAML::anchor_t,
                    YAML::EmitterStyle::value) override {
        node(mark);
    }
    void OnMapEnd() override {}

private:
    void node(const YAML::Mark& mark) {
        if (nodes.size() < starts.size()) nodes.push_back(mark);
    }
};

/// The marks of the text's first two documents at most. Not YAML::LoadAll: on a token that no
/// node starts with (a ',' outside a flow list), yaml-cpp 0.7's parser reports an empty
/// document there without consuming the token, again and again, and LoadAll collects them
/// until memory runs out (jbeder/yaml-cpp#1040, fixed upstream by #1319; found by
/// tests/fuzz/fuzz_spec). Two documents starting at one place are that token: malformed YAML.
DocumentMarks first_documents(const SpecReader& r, const std::string& text) {
    std::istringstream in(text);
    YAML::Parser parser(in);
    DocumentMarks marks;
    while (marks.starts.size() < 2 && parser.HandleNextDocument(marks)) {
    }
    if (marks.starts.size() == 2 && marks.starts[0].pos == marks.starts[1].pos) {
        const YAML::Mark& at = marks.starts[1];
        const std::string token = std::size_t(at.pos) < text.size() ? text.substr(at.pos, 1) : "";
        throw SpecError(where(r.file, at) + ": malformed YAML: unexpected '" + token +
                        "'; allowed: a mapping of keys to values (',' only inside [ ] or { })");
    }
    return marks;
}

/// The end of the quoted scalar opening at line[i] (the closing quote's index), or npos when it
/// does not close on its line. Double quotes escape with '\\', single quotes by doubling.
std::size_t closing_quote(std::string_view line, std::size_t i) {
    const char q = line[i];
    for (std::size_t j = i + 1; j < line.size(); ++j) {
        if (q == '"' && line[j] == '\\') {
            ++j;
        } else if (line[j] == q) {
            if (q == '\'' && j + 1 < line.size() && line[j + 1] == '\'') {
                ++j;
                continue;
            }
            return j;
        }
    }
    return std::string_view::npos;
}

/// yaml-cpp lets a quoted scalar that is never closed run on over the lines after it, so its
/// key swallows them: a spec's quoted values must open and close on one line. Quotes inside
/// a plain scalar ("seed's"), comments and block scalars (| or >) are left alone.
void check_quotes_closed(const SpecReader& r, const std::string& text) {
    std::size_t line_no = 0, block_indent = std::string::npos;
    for (std::size_t start = 0; start <= text.size(); ++line_no) {
        std::size_t end = text.find('\n', start);
        if (end == std::string::npos) end = text.size();
        const std::string_view line(text.data() + start, end - start);
        start = end + 1;
        const std::size_t indent = line.find_first_not_of(" \t");
        if (indent == std::string_view::npos) continue;
        if (block_indent != std::string::npos && indent > block_indent) continue;
        block_indent = std::string::npos;
        bool scalar_start = true;  // the next non-blank character may open a scalar
        char last = 0, before = 0; // the last two characters outside quotes and comments
        for (std::size_t i = indent; i < line.size(); ++i) {
            const char c = line[i];
            if (c == '#' && (i == 0 || line[i - 1] == ' ' || line[i - 1] == '\t')) break;
            if (c == ' ' || c == '\t') continue;
            if ((c == '"' || c == '\'') && scalar_start) {
                const std::size_t j = closing_quote(line, i);
                if (j == std::string_view::npos) {
                    YAML::Mark at;
                    at.line = int(line_no);
                    at.column = int(i);
                    throw SpecError(where(r.file, at) + ": malformed YAML: the " +
                                    (c == '"' ? "double" : "single") +
                                    "-quoted value opened here is not closed on its line; "
                                    "allowed: a quoted value that ends on the line it starts");
                }
                i = j;
                before = last;
                last = c;
                scalar_start = false;
                continue;
            }
            scalar_start = c == ':' || c == '-' || c == '[' || c == '{' || c == ',' || c == '?';
            before = last;
            last = c;
        }
        const auto block = [](char x) { return x == '|' || x == '>'; };
        if (block(last) || ((last == '-' || last == '+') && block(before))) block_indent = indent;
    }
}

/// The one document of the text, which must be a mapping.
/// The length of the UTF-8 sequence at text[i] (1 to 4), or 0 when it is not valid UTF-8 (a
/// stray continuation byte, a truncated or overlong sequence, a surrogate, beyond U+10FFFF).
std::size_t utf8_length(std::string_view text, std::size_t i) {
    const auto byte = [&](std::size_t k) { return static_cast<unsigned char>(text[k]); };
    const unsigned char b = byte(i);
    if (b < 0x80) return 1;
    const std::size_t n = b >= 0xF0 ? 4 : b >= 0xE0 ? 3 : b >= 0xC2 ? 2 : 0;
    if (n == 0 || b > 0xF4 || i + n > text.size()) return 0;
    for (std::size_t k = 1; k < n; ++k)
        if ((byte(i + k) & 0xC0) != 0x80) return 0;
    const unsigned char c = byte(i + 1);
    if ((b == 0xE0 && c < 0xA0) || (b == 0xED && c >= 0xA0) || (b == 0xF0 && c < 0x90) ||
        (b == 0xF4 && c >= 0x90))
        return 0;
    return n;
}

/// A spec is UTF-8 text without control characters (tab and line ends aside), as YAML
/// requires: names and paths go into JSON, CSV and folder names, which need it.
void check_text(const SpecReader& r, const std::string& text) {
    YAML::Mark at;
    at.line = at.column = 0;
    for (std::size_t i = 0; i < text.size();) {
        const unsigned char b = static_cast<unsigned char>(text[i]);
        const std::size_t n = utf8_length(text, i);
        const bool control = b == 0x7f || (b < 0x20 && b != '\t' && b != '\n' && b != '\r');
        if (n == 0 || control) {
            char hex[8];
            std::snprintf(hex, sizeof hex, "0x%02X", unsigned(b));
            throw SpecError(where(r.file, at) + ": malformed text: byte " + hex + " is " +
                            (control ? "a control character" : "not UTF-8") +
                            "; allowed: UTF-8 text without control characters (save the file "
                            "as UTF-8)");
        }
        ++at.column;
        if (b == '\n') {
            ++at.line;
            at.column = 0;
        }
        i += n;
    }
}

YAML::Node parse_document(const SpecReader& r, const std::string& text) {
    check_text(r, text);
    check_quotes_closed(r, text);
    YAML::Node doc;
    try {
        const DocumentMarks marks = first_documents(r, text);
        if (marks.starts.size() > 1) {
            const YAML::Mark& at = marks.nodes.size() > 1 ? marks.nodes[1] : marks.starts[1];
            throw SpecError(where(r.file, at) +
                            ": a second YAML document; allowed: one document per spec file");
        }
        doc = YAML::Load(text);
    } catch (const YAML::Exception& ex) {
        throw SpecError(where(r.file, ex.mark) + ": malformed YAML: " + ex.msg);
    }
    const std::string allowed = "a mapping with " + keys_allowed_in("");
    if (doc.IsNull()) throw SpecError(r.file + ":1:1: spec is empty; allowed: " + allowed);
    if (!doc.IsMap()) {
        fail(r, doc.Mark(), "(top level)", node_text(doc), "is " + kind(doc) + ", not a mapping",
             allowed);
    }
    return doc;
}

/// The resolved values under a section as one line, e.g. "{images: false, labels: false}";
/// a list as "[{name: train, fraction: 0.8}, ...]"; a leaf's value (of item `item`).
std::string resolved_text(const Spec& spec, const std::string& section, std::size_t item = 0) {
    if (const SchemaEntry* leaf = find_schema_entry(section))
        return value_to_yaml(leaf->get(spec, item), leaf->type);
    if (const SchemaList* list = find_schema_list(section)) {
        std::string out = "[";
        for (std::size_t i = 0; i < list->size(spec); ++i)
            out += (i ? ", " : "") + resolved_text(spec, section + "[]", i);
        return out + "]";
    }
    std::string out;
    for (const SchemaEntry& e : spec_schema()) {
        if (e.key.compare(0, section.size() + 1, section + ".") != 0) continue;
        out += (out.empty() ? "{" : ", ") + e.key.substr(section.size() + 1) + ": " +
               value_to_yaml(e.get(spec, item), e.type);
    }
    return out + "}";
}

/// The mark of the first of `keys` that was met, else of the nearest section above the last
/// one that was written, else the start of the file (a key left out has no mark of its own).
YAML::Mark first_mark(const SpecReader& r, const std::vector<std::string>& keys) {
    for (const std::string& key : keys)
        if (const auto mark = r.key_marks.find(key); mark != r.key_marks.end()) return mark->second;
    for (std::string section = keys.back(); !section.empty();) {
        const std::size_t dot = section.rfind('.');
        section = dot == std::string::npos ? "" : section.substr(0, dot);
        if (const auto mark = r.key_marks.find(section); mark != r.key_marks.end())
            return mark->second;
    }
    YAML::Mark start;
    start.line = start.column = 0;
    return start;
}

/// What is wrong with item `i` under `rule` (empty: it holds).
std::string rule_problem(const SchemaRule& rule, const Spec& spec, std::size_t i) {
    if (rule.diagnose) return rule.diagnose(spec, i);
    return rule.holds(spec, i) ? std::string() : rule.problem;
}

/// `spec` with its varied keys at the ends of their ranges: each key alone at its lowest and
/// at its highest, then all at their lowest and all at their highest, each with a note for
/// messages. A rule between keys must hold for every sensor a variant can draw.
std::vector<std::pair<Spec, std::string>> varied_extremes(const Spec& spec) {
    std::vector<std::pair<Spec, std::string>> out;
    if (spec.varied.empty()) return out;
    for (const bool high : {false, true}) {
        const char* end = high ? "highest" : "lowest";
        Spec all = spec;
        for (const auto& [key, factor] : spec.varied) {
            const double value = high ? highest(factor) : lowest(factor);
            Spec one = spec;
            set_varied_value(one, key, value);
            set_varied_value(all, key, value);
            out.emplace_back(std::move(one), " (with " + key + " at its " + end + ", " +
                                                 format_number(value) + ")");
        }
        out.emplace_back(std::move(all), std::string(" (with every varied key at its ") + end +
                                             ")");
    }
    return out;
}

void check_rules_on(const SpecReader& r, const Spec& spec, bool check_files,
                    const std::string& note);

void check_rules(const SpecReader& r, const Spec& spec, bool check_files) {
    check_rules_on(r, spec, check_files, "");
    for (const auto& [extreme, note] : varied_extremes(spec))
        check_rules_on(r, extreme, false, note);
}

void check_rules_on(const SpecReader& r, const Spec& spec, bool check_files,
                    const std::string& note) {
    for (const SchemaRule& rule : spec_rules()) {
        if (rule.reads_files && !check_files) continue;
        const std::size_t brackets = rule.key.find("[]");
        if (brackets == std::string::npos) {
            const std::string problem = rule_problem(rule, spec, 0);
            if (problem.empty()) continue;
            fail(r, first_mark(r, {rule.key}), rule.key, resolved_text(spec, rule.key),
                 problem + note, rule.allowed);
        }
        const std::string list = rule.key.substr(0, brackets);
        for (std::size_t i = 0; i < find_schema_list(list)->size(spec); ++i) {
            const std::string problem = rule_problem(rule, spec, i);
            if (problem.empty()) continue;
            const std::string item = list + "[" + std::to_string(i) + "]";
            const std::string key = item + rule.key.substr(brackets + 2);
            fail(r, first_mark(r, {key, item, list}), key, resolved_text(spec, rule.key, i),
                 problem + note, rule.allowed);
        }
    }
}

std::string read_file(const std::filesystem::path& path) {
    const std::string name = path.string();
    std::error_code ec;
    if (std::filesystem::is_directory(path, ec)) {
        throw SpecError(name + ": cannot read spec file: it is a directory");
    }
    std::ifstream in(path, std::ios::binary);
    if (!in) throw SpecError(name + ": cannot read spec file: " + std::strerror(errno));
    std::ostringstream text;
    text << in.rdbuf();
    if (in.bad()) throw SpecError(name + ": cannot read spec file: read error");
    return text.str();
}

} // namespace
} // namespace detail

std::filesystem::path resolve_spec_path(const Spec& spec, const std::filesystem::path& written) {
    if (written.is_absolute()) return written;
    return spec.source_path.parent_path() / written;
}

std::filesystem::path spectra_directory(const Spec& spec) {
    if (spec.sensor.spectra_dir.empty())
        return std::filesystem::path(CHROMASIM_SOURCE_DIR) / "assets" / "spectra";
    return resolve_spec_path(spec, spec.sensor.spectra_dir);
}

namespace {

Spec parse(const std::string& yaml_text, const std::string& display_name, bool check_files) {
    detail::SpecReader reader{display_name, {}, {}, {}};
    detail::read_map(reader, detail::parse_document(reader, yaml_text), {});
    Spec spec = default_spec();
    for (const auto& [name, size] : reader.list_sizes) {
        const SchemaList* list = find_schema_list(name);
        list->resize(spec, 0); // the items written start from the item defaults
        list->resize(spec, size);
    }
    for (const detail::ReadValue& v : reader.values) {
        v.entry->set(spec, v.item, v.value);
    }
    spec.source_path = display_name; // relative paths in the spec start at its folder
    detail::check_rules(reader, spec, check_files);
    spec.source_path.clear(); // set by load_spec only
    spec.resolved_yaml = resolved_spec_yaml(spec);
    return spec;
}

} // namespace

Spec parse_spec(const std::string& yaml_text, const std::string& display_name) {
    return parse(yaml_text, display_name, true);
}

Spec parse_stored_spec(const std::string& resolved_yaml, const std::string& source) {
    Spec spec = parse(resolved_yaml, source, false);
    spec.source_path = source;
    spec.resolved_yaml = resolved_yaml; // the stored bytes, whatever a new resolve would print
    return spec;
}

Spec load_spec(const std::filesystem::path& path) {
    Spec spec = parse_spec(detail::read_file(path), path.string());
    spec.source_path = path;
    return spec;
}

} // namespace chromasim::generators
