#include "generators/output/manifest.hpp"

#include "generators/io/build_info.hpp"
#include "generators/io/file_io.hpp"

#include <nlohmann/json.hpp>

namespace chromasim::generators {

using Json = nlohmann::ordered_json; // keys in the order written: a stable, readable file

std::string trial_record_json(const TrialRecord& r) {
    Json j{{"trial", r.trial},       {"split", r.split},
           {"frames", r.frames},     {"images", r.images},
           {"solves", r.solves},     {"reused_solves", r.reused_solves},
           {"renders", r.renders},   {"flagged_frames", r.flagged_frames},
           {"files", Json::object()}};
    for (const auto& [path, sha] : r.files)
        j["files"][path] = sha;
    return j.dump(1) + "\n";
}

std::optional<TrialRecord> parse_trial_record(const std::string& text) {
    const Json j = Json::parse(text, nullptr, /*allow_exceptions=*/false);
    if (j.is_discarded() || !j.is_object()) return std::nullopt;
    try {
        TrialRecord r;
        r.trial = j.at("trial").get<int>();
        r.split = j.at("split").get<std::string>();
        r.frames = j.at("frames").get<int>();
        r.images = j.at("images").get<int>();
        r.solves = j.at("solves").get<int>();
        r.reused_solves = j.at("reused_solves").get<int>();
        r.renders = j.at("renders").get<int>();
        r.flagged_frames = j.at("flagged_frames").get<int>();
        for (const auto& [path, sha] : j.at("files").items())
            r.files[path] = sha.get<std::string>();
        return r;
    } catch (const Json::exception&) {
        return std::nullopt;
    }
}

namespace {

Json counts(int trials, int frames, int images) {
    return Json{{"trials", trials}, {"frames", frames}, {"images", images}};
}

Json split_counts(const Spec& spec, const std::vector<TrialRecord>& records) {
    Json splits = Json::object();
    for (const auto& s : spec.splits) // the spec's order, every split even if empty
        splits[s.name] = counts(0, 0, 0);
    for (const TrialRecord& r : records) {
        Json& c = splits[r.split];
        if (c.is_null()) c = counts(0, 0, 0);
        c["trials"] = c["trials"].get<int>() + 1;
        c["frames"] = c["frames"].get<int>() + r.frames;
        c["images"] = c["images"].get<int>() + r.images;
    }
    return splits;
}

} // namespace

std::string manifest_json(const Spec& spec, const std::string& spec_text, int max_trials,
                          const ManifestInfo& info, const std::vector<TrialRecord>& records,
                          const std::map<std::string, std::string>& checksums) {
    int frames = 0, images = 0, solves = 0, reused = 0, renders = 0, flagged = 0;
    for (const TrialRecord& r : records) {
        frames += r.frames;
        images += r.images;
        solves += r.solves;
        reused += r.reused_solves;
        renders += r.renders;
        flagged += r.flagged_frames;
    }
    Json deps = Json::object();
    for (const auto& [name, version] : dependency_versions())
        deps[name] = version.empty() ? Json(nullptr) : Json(version);
    Json j;
    j["format"] = "chromasim dataset (docs/DATASET_FORMAT.md)";
    j["manifest_version"] = 1;
    j["name"] = spec.name;
    j["chromasim_version"] = CHROMASIM_VERSION;
    j["instruction_set"] = CHROMASIM_ARCH; // the build's (CMakeLists.txt, CHROMASIM_ARCH)
    j["dependencies"] = deps;
    j["spec"] = Json{{"source", spec.source_path.string()},
                     {"file", "spec.resolved.yaml"},
                     {"sha256", sha256_hex(spec_text)},
                     {"resolved_yaml", spec_text}};
    j["slice"] = max_trials > 0 ? Json{{"max_trials", max_trials}} : Json(nullptr);
    j["planned_trials"] = info.planned_trials;
    j["fingers"] = spec.fingers.count;
    j["counts"] = counts(int(records.size()), frames, images);
    j["counts"]["label_rows"] = spec.outputs.labels ? frames : 0;
    j["splits"] = split_counts(spec, records);
    j["mechanics"] = Json{{"solves", solves},
                          {"reused_solves", reused},
                          {"renders", renders},
                          {"flagged_frames", flagged},
                          {"mesh", Json{{"level", info.mesh_level},
                                        {"element_order", info.element_order},
                                        {"nodes", info.mesh_nodes},
                                        {"tets", info.mesh_tets}}}};
    if (info.strain)
        j["strain_grid"] = Json{{"nx", info.strain_nx},
                                {"ny", info.strain_ny},
                                {"half_width_x_mm", info.strain_half_width_x_mm},
                                {"half_width_y_mm", info.strain_half_width_y_mm}};
    j["checksum"] = "sha256";
    j["files"] = Json::object();
    for (const auto& [path, sha] : checksums) // std::map: sorted by path
        j["files"][path] = sha;
    return j.dump(2) + "\n";
}

std::string part_json(const PartInfo& p) {
    Json j;
    j["format"] = "chromasim dataset part (docs/DATASET_FORMAT.md, Shards and merge)";
    j["part_version"] = 1;
    j["chromasim_version"] = p.chromasim_version;
    j["instruction_set"] = p.instruction_set;
    j["shard"] = Json{{"index", p.shard.index}, {"count", p.shard.count}};
    j["spec"] = Json{{"source", p.spec_source}, {"sha256", p.spec_sha256}};
    j["max_trials"] = p.max_trials;
    j["trials"] = p.trials;
    const ManifestInfo& i = p.info;
    j["planned_trials"] = i.planned_trials;
    j["mesh"] = Json{{"level", i.mesh_level},
                     {"element_order", i.element_order},
                     {"nodes", i.mesh_nodes},
                     {"tets", i.mesh_tets}};
    j["strain_grid"] = i.strain ? Json{{"nx", i.strain_nx},
                                       {"ny", i.strain_ny},
                                       {"half_width_x_mm", i.strain_half_width_x_mm},
                                       {"half_width_y_mm", i.strain_half_width_y_mm}}
                                : Json(nullptr);
    return j.dump(2) + "\n";
}

std::optional<PartInfo> parse_part_json(const std::string& text) {
    const Json j = Json::parse(text, nullptr, /*allow_exceptions=*/false);
    if (j.is_discarded() || !j.is_object()) return std::nullopt;
    try {
        if (j.at("part_version").get<int>() != 1) return std::nullopt;
        PartInfo p;
        p.chromasim_version = j.at("chromasim_version").get<std::string>();
        p.instruction_set = j.at("instruction_set").get<std::string>();
        p.shard.index = j.at("shard").at("index").get<int>();
        p.shard.count = j.at("shard").at("count").get<int>();
        p.spec_source = j.at("spec").at("source").get<std::string>();
        p.spec_sha256 = j.at("spec").at("sha256").get<std::string>();
        p.max_trials = j.at("max_trials").get<int>();
        p.trials = j.at("trials").get<std::vector<int>>();
        ManifestInfo& i = p.info;
        i.planned_trials = j.at("planned_trials").get<int>();
        i.mesh_level = j.at("mesh").at("level").get<std::string>();
        i.element_order = j.at("mesh").value("element_order", 1);
        i.mesh_nodes = j.at("mesh").at("nodes").get<int>();
        i.mesh_tets = j.at("mesh").at("tets").get<int>();
        const Json& grid = j.at("strain_grid");
        i.strain = !grid.is_null();
        if (i.strain) {
            i.strain_nx = grid.at("nx").get<int>();
            i.strain_ny = grid.at("ny").get<int>();
            i.strain_half_width_x_mm = grid.at("half_width_x_mm").get<double>();
            i.strain_half_width_y_mm = grid.at("half_width_y_mm").get<double>();
        }
        return p;
    } catch (const Json::exception&) {
        return std::nullopt;
    }
}

} // namespace chromasim::generators
