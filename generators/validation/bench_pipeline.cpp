// `chromasim bench pipeline`: the whole job (generate) timed per stage on real specs.
#include "generators/validation/bench.hpp"

#include "generators/pipeline/generate.hpp"
#include "generators/spec/spec.hpp"
#include "generators/spec/spec_schema.hpp"

#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <iomanip>
#include <ostream>
#include <sstream>
#include <vector>

namespace chromasim::generators {

namespace {

double median(std::vector<double> v) {
    std::sort(v.begin(), v.end());
    const std::size_t n = v.size();
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/// One spec to time: the spec, its label and the trials to run (0: all).
struct PipelineCase {
    std::string label;
    Spec spec;
    int max_trials = 0;
};

/// Medians over the repeats of one case; times per frame in ms.
struct PipelineRow {
    GenerateReport last; ///< counts (frames, renders, ...) are the same in every run
    double fps = 0, frame_ms = 0, mechanics_ms = 0, render_ms = 0, write_ms = 0, other_ms = 0;
    double precompute_s = 0, light_cache_s = 0;
};

/// A fresh folder under the system's temporary directory, unique to this process and run.
std::filesystem::path scratch_dir(int run) {
    return std::filesystem::temp_directory_path() /
           ("chromasim-bench-pipeline-" + std::to_string(::getpid()) + "-" + std::to_string(run));
}

/// generate() into a temporary folder, removed afterwards (also when generate throws).
GenerateReport run_once(const PipelineCase& c, int run) {
    GenerateOptions options;
    options.out_dir = scratch_dir(run);
    options.quiet = true;
    options.max_trials = c.max_trials;
    std::filesystem::remove_all(options.out_dir);
    std::ostringstream log;
    struct Cleanup {
        std::filesystem::path dir;
        ~Cleanup() {
            std::error_code ec;
            std::filesystem::remove_all(dir, ec);
        }
    } cleanup{options.out_dir};
    return generate(c.spec, options, log);
}

PipelineRow time_case(const PipelineCase& c, int repeats, int& run) {
    std::vector<double> frame, mech, rend, write, pre, cache;
    PipelineRow row;
    for (int i = 0; i < repeats; ++i) {
        row.last = run_once(c, run++);
        const GenerateReport& r = row.last;
        const double n = std::max(r.frames, 1);
        const double frames_s = r.total_s - r.precompute_s;
        frame.push_back(1e3 * frames_s / n);
        mech.push_back(1e3 * r.mechanics_s / n);
        rend.push_back(1e3 * r.render_s / n);
        write.push_back(1e3 * r.write_s / n);
        pre.push_back(r.precompute_s);
        cache.push_back(r.light_cache_s);
    }
    row.frame_ms = median(frame);
    row.fps = 1e3 / row.frame_ms;
    row.mechanics_ms = median(mech);
    row.render_ms = median(rend);
    row.write_ms = median(write);
    row.other_ms = std::max(0.0, row.frame_ms - row.mechanics_ms - row.render_ms - row.write_ms);
    row.precompute_s = median(pre);
    row.light_cache_s = median(cache);
    return row;
}

/// "12.3 (45%)": a per-frame time and its share of the frame.
std::string share(double ms, double frame_ms) {
    std::ostringstream s;
    s << std::fixed << std::setprecision(1) << ms << " (" << std::setprecision(0)
      << 100.0 * ms / frame_ms << "%)";
    return s.str();
}

void print_row(const PipelineCase& c, const PipelineRow& r, std::ostream& out) {
    const Spec& s = c.spec;
    out << "| " << c.label << " | " << r.last.trials << " | " << r.last.frames << " | "
        << r.last.solves << " / " << r.last.renders << " | " << s.render.integrator << ", "
        << s.render.samples_per_pixel << " spp, " << s.render.width_px << " x "
        << s.render.height_px << " | " << std::fixed << std::setprecision(1) << r.precompute_s
        << " (" << r.light_cache_s << ") | " << std::setprecision(2) << r.fps << " | "
        << std::setprecision(1) << r.frame_ms << " | " << share(r.mechanics_ms, r.frame_ms) << " | "
        << share(r.render_ms, r.frame_ms) << " | " << share(r.write_ms, r.frame_ms) << " | "
        << share(r.other_ms, r.frame_ms) << " |\n";
}

std::vector<PipelineCase> pipeline_cases(const PipelineBenchOptions& o) {
    std::vector<PipelineCase> cases;
    cases.push_back({"quickstart", load_spec(o.spec_dir / "quickstart.yaml"), 0});
    Spec slice = load_spec(o.spec_dir / "seed000_train.yaml");
    if (!o.integrator.empty()) slice.render.integrator = o.integrator;
    if (o.samples_per_pixel > 0) slice.render.samples_per_pixel = o.samples_per_pixel;
    slice.resolved_yaml = resolved_spec_yaml(slice);
    cases.push_back(
        {"seed000_train, first " + std::to_string(o.trials) + " trial" + (o.trials == 1 ? "" : "s"),
         slice, o.trials});
    return cases;
}

} // namespace

void bench_pipeline(const PipelineBenchOptions& o, std::ostream& out) {
    const std::vector<PipelineCase> cases = pipeline_cases(o);
    out << "generate, whole pipeline, median of " << o.repeats
        << " runs; frames are stereo (both fingertips) and labelled; ms per frame; precompute "
           "(mesh, factorization, light cache) apart, no precompute cache\n\n"
        << "| spec | trials | frames | solves / renders | render | precompute s (light cache) "
           "| frames/s | ms/frame | mechanics | render | writing | other |\n"
        << "|---|---|---|---|---|---|---|---|---|---|---|---|\n";
    int run = 0;
    for (const PipelineCase& c : cases) {
        print_row(c, time_case(c, o.repeats, run), out);
        out.flush();
    }
    out << "\nsolves and renders are per fingertip: a hold frame reuses its finger's solve and "
           "image\n";
}

} // namespace chromasim::generators
