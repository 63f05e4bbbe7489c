// The YAML side of the spec: the only file that includes yaml-cpp. It checks the shape of the
// document (mappings, lists, scalars, known keys) and where each value sits in the file; the
// schema (spec_schema.cpp) converts and range-checks the values and fills the Spec.
#include "generators/spec.hpp"
#include "generators/spec_schema.hpp"

#include <yaml-cpp/yaml.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <map>
#include <sstream>
#include <utility>
#include <vector>

namespace chromasim::generators {
namespace detail {
namespace { // internal linkage: these names are common

/// What one read of a spec text collects.
struct SpecReader {
    std::string file;                                             ///< name used in messages
    std::vector<std::pair<const SchemaEntry*, SpecValue>> values; ///< in file order
    std::map<std::string, YAML::Mark> key_marks;                  ///< every dotted key met
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

SpecValue read_rgb(const SpecReader& r, const SchemaEntry& entry, const YAML::Node& key_node,
                   const YAML::Node& value) {
    const std::string allowed = describe_allowed(entry);
    if (value.IsNull()) fail(r, value_mark(key_node, value), entry.key, "", "is empty", allowed);
    if (!value.IsSequence()) {
        fail(r, value.Mark(), entry.key, node_text(value), "is " + kind(value) + ", not a list",
             allowed);
    }
    if (value.size() != 3) {
        fail(r, value.Mark(), entry.key, node_text(value),
             "has " + std::to_string(value.size()) + " items", allowed);
    }
    Rgb rgb{};
    for (std::size_t i = 0; i < 3; ++i) {
        const std::string key = entry.key + "[" + std::to_string(i) + "]";
        rgb[i] = std::get<double>(read_scalar(r, entry, key, value, value[i]));
    }
    return rgb;
}

void read_map(SpecReader& r, const YAML::Node& map, const std::string& section);

/// A section's value: a mapping, or empty (all defaults).
void read_section(SpecReader& r, const std::string& key, const YAML::Node& value) {
    if (value.IsMap()) return read_map(r, value, key);
    if (value.IsNull()) return;
    fail(r, value.Mark(), key, node_text(value), "is " + kind(value) + ", not a mapping",
         "a mapping with " + keys_allowed_in(key));
}

[[noreturn]] void unknown_key(const SpecReader& r, const YAML::Node& key_node,
                              const std::string& key, const std::string& name,
                              const std::string& section) {
    const std::string near = closest_match(name, schema_children(section));
    std::string hint = near.empty() ? "" : " (did you mean '" + near + "'?)";
    if (name.find('.') != std::string::npos) {
        hint = " (a dotted key is written nested: one mapping per dot)";
    }
    throw SpecError(where(r.file, key_node.Mark()) + ": " + key + ": unknown key '" + name + "'" +
                    hint + "; allowed " + keys_allowed_in(section));
}

/// The key's name within its mapping; rejects keys that are not plain text.
std::string key_name(const SpecReader& r, const YAML::Node& key_node, const std::string& section) {
    if (key_node.IsScalar()) return key_node.Scalar();
    fail(r, key_node.Mark(), section.empty() ? "(top level)" : section, node_text(key_node),
         "is not a valid key (" + kind(key_node) + ")", keys_allowed_in(section));
}

void read_entry(SpecReader& r, const std::string& section, const YAML::Node& key_node,
                const YAML::Node& value) {
    const std::string name = key_name(r, key_node, section);
    const std::string key = section.empty() ? name : section + "." + name;
    const auto [first, inserted] = r.key_marks.emplace(key, key_node.Mark());
    if (!inserted) {
        fail(r, key_node.Mark(), key, name,
             "is given twice (first at line " + std::to_string(first->second.line + 1) + ")",
             "each key once per mapping");
    }
    if (!name.empty() && name.find('.') == std::string::npos) {
        if (const SchemaEntry* entry = find_schema_entry(key)) {
            const bool list = entry->type == ValueType::Rgb || entry->type == ValueType::Vec3;
            r.values.emplace_back(entry, list ? read_rgb(r, *entry, key_node, value)
                                              : read_scalar(r, *entry, key, key_node, value));
            return;
        }
        if (is_schema_section(key)) return read_section(r, key, value);
    }
    unknown_key(r, key_node, key, name, section);
}

void read_map(SpecReader& r, const YAML::Node& map, const std::string& section) {
    for (const auto& pair : map) {
        read_entry(r, section, pair.first, pair.second);
    }
}

/// The one document of the text, which must be a mapping.
YAML::Node parse_document(const SpecReader& r, const std::string& text) {
    std::vector<YAML::Node> docs;
    try {
        docs = YAML::LoadAll(text);
    } catch (const YAML::Exception& ex) {
        throw SpecError(where(r.file, ex.mark) + ": malformed YAML: " + ex.msg);
    }
    const std::string allowed = "a mapping with " + keys_allowed_in("");
    if (docs.empty() || docs[0].IsNull()) {
        throw SpecError(r.file + ":1:1: spec is empty; allowed: " + allowed);
    }
    if (docs.size() > 1) {
        throw SpecError(where(r.file, docs[1].Mark()) +
                        ": a second YAML document; allowed: one document per spec file");
    }
    if (!docs[0].IsMap()) {
        fail(r, docs[0].Mark(), "(top level)", node_text(docs[0]),
             "is " + kind(docs[0]) + ", not a mapping", allowed);
    }
    return docs[0];
}

/// "{images: false, labels: false, markers: false}": the resolved values under a section.
std::string resolved_text(const Spec& spec, const std::string& section) {
    if (const SchemaEntry* leaf = find_schema_entry(section))
        return value_to_yaml(leaf->get(spec), leaf->type);
    std::string out;
    for (const SchemaEntry& e : spec_schema()) {
        if (e.key.compare(0, section.size() + 1, section + ".") != 0) continue;
        out += (out.empty() ? "{" : ", ") + e.key.substr(section.size() + 1) + ": " +
               value_to_yaml(e.get(spec), e.type);
    }
    return out + "}";
}

void check_rules(const SpecReader& r, const Spec& spec) {
    for (const SchemaRule& rule : spec_rules()) {
        if (rule.holds(spec)) continue;
        const auto mark = r.key_marks.find(rule.key);
        fail(r, mark == r.key_marks.end() ? YAML::Mark::null_mark() : mark->second, rule.key,
             resolved_text(spec, rule.key), rule.problem, rule.allowed);
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

Spec parse_spec(const std::string& yaml_text, const std::string& display_name) {
    detail::SpecReader reader{display_name, {}, {}};
    detail::read_map(reader, detail::parse_document(reader, yaml_text), "");
    Spec spec = default_spec();
    for (const auto& [entry, value] : reader.values) {
        entry->set(spec, value);
    }
    spec.source_path = display_name; // relative paths in the spec start at its folder
    detail::check_rules(reader, spec);
    spec.source_path.clear(); // set by load_spec only
    spec.resolved_yaml = resolved_spec_yaml(spec);
    return spec;
}

Spec load_spec(const std::filesystem::path& path) {
    Spec spec = parse_spec(detail::read_file(path), path.string());
    spec.source_path = path;
    return spec;
}

} // namespace chromasim::generators
