// chromasim._core: the pybind11 adapter of generators/pipeline/simulator.hpp (the only file
// with pybind11 includes besides frames.cpp). Python's chromasim/sim.py wraps it; users call
// that, not this.
#include "python/src/frames.hpp"

#include "generators/pipeline/generate.hpp"
#include "generators/plan/plan.hpp"
#include "generators/plan/sensor_variants.hpp"
#include "generators/spec/spec.hpp"

#include <pybind11/stl.h>

#include <array>
#include <cmath>
#include <limits>
#include <optional>

namespace chromasim::python {

namespace {

using generators::FingerLoad;
using generators::Spec;
using generators::SpecError;

/// A value the caller passed, checked: finite and within [min, max] (or above `min` when
/// `open_min`), else ValueError naming the argument, its value and what is allowed.
double checked(const char* name, double value, double min, double max, bool open_min,
               const char* unit) {
    const bool ok = std::isfinite(value) && (open_min ? value > min : value >= min) && value <= max;
    if (!ok) {
        std::string allowed = open_min ? "a finite number > " : "a finite number >= ";
        allowed += py::str(py::float_(min)).cast<std::string>();
        if (std::isfinite(max)) allowed += " and <= " + py::str(py::float_(max)).cast<std::string>();
        throw py::value_error(std::string(name) + " = " + py::repr(py::float_(value)).cast<std::string>() +
                              ": allowed: " + allowed + " (" + unit + ")");
    }
    return value;
}

constexpr double kInf = std::numeric_limits<double>::infinity();

Eigen::Vector2d checked_pair(const char* name, const std::array<double, 2>& v, const char* unit) {
    checked(name, v[0], -kInf, kInf, false, unit);
    checked(name, v[1], -kInf, kInf, false, unit);
    return {v[0], v[1]};
}

/// The spec: read from `path`, or parsed from `text` (named `name` in messages); `seed`
/// replaces spec.seed.
Spec read_spec(const std::optional<std::string>& path, const std::optional<std::string>& text,
               const std::string& name, std::optional<std::uint64_t> seed) {
    if (path.has_value() == text.has_value())
        throw py::value_error("give a spec file's path or a spec's text, not both or neither");
    Spec spec = path ? generators::load_spec(*path) : generators::parse_spec(*text, name);
    if (seed) spec.seed = *seed;
    return spec;
}

/// The spec of one sensor: a spec that varies its sensor needs `variant`, an index into its
/// plan's sensors (the sensors `generate` draws).
Spec one_sensor(const Spec& spec, std::optional<int> variant) {
    if (!generators::varies_sensor(spec)) {
        if (variant) throw py::value_error("variant: the spec varies no sensor key");
        return spec;
    }
    const generators::Plan plan = generators::make_plan(spec);
    const int count = int(plan.sensors.size());
    if (!variant)
        throw SpecError(spec.source_path.string() + ": the spec varies its sensor (" +
                        generators::what_varies(spec) +
                        "): give variant = 0 to " + std::to_string(count - 1) +
                        ", one of the sensors generate draws");
    if (*variant < 0 || *variant >= count)
        throw py::index_error("variant " + std::to_string(*variant) + ": the spec draws " +
                              std::to_string(count) + " sensors (0 to " +
                              std::to_string(count - 1) + ")");
    return generators::sensor_spec(spec, plan.sensors[std::size_t(*variant)]);
}

/// The index of the spec object named `object` (or at that index).
int object_index(const Spec& spec, const py::object& object) {
    if (py::isinstance<py::int_>(object)) {
        const int k = object.cast<int>();
        if (k < 0 || k >= int(spec.objects.size()))
            throw py::index_error("object " + std::to_string(k) + ": the spec has " +
                                  std::to_string(spec.objects.size()) + " objects");
        return k;
    }
    const std::string name = object.cast<std::string>();
    std::string names;
    for (std::size_t k = 0; k < spec.objects.size(); ++k) {
        if (spec.objects[k].name == name) return int(k);
        names += (k ? ", " : "") + spec.objects[k].name;
    }
    throw py::value_error("object '" + name + "': the spec's objects are " + names);
}

/// The fingertips of a grasp of spec object `object` at `mu` (one per spec finger, or `count`).
std::shared_ptr<Contact> make_contact(const std::shared_ptr<generators::Simulator>& sim,
                                      const py::object& object, const std::vector<double>& mu,
                                      std::optional<double> direction_deg) {
    const Spec& spec = sim->spec();
    const int k = object_index(spec, object);
    const generators::ObjectSource& source = sim->settings().objects[std::size_t(k)];
    const int count = int(mu.size());
    if (count < 1 || count > 2)
        throw py::value_error("mu: give one value per fingertip (1 or 2 values), got " +
                              std::to_string(count));
    Spec protocol = spec;
    if (direction_deg) protocol.protocol.load_direction_deg = *direction_deg;
    auto contact = std::make_shared<Contact>(sim);
    contact->object = source.object.name;
    for (int f = 0; f < count; ++f) {
        checked("mu", mu[std::size_t(f)], 0.0, 10.0, true, "Coulomb coefficient");
        generators::FingerSetup setup = generators::grasp_finger(protocol, source.object,
                                                                 mu[std::size_t(f)], f);
        contact->setups.push_back(setup);
        contact->fingers.emplace_back(
            *sim, generators::object_shape(source, generators::posed_object(source.object, setup)));
    }
    return contact;
}

/// The loads of a contact's step: grip on every fingertip, `load_N` shared equally along each
/// fingertip's direction (force control), or the object's travel (displacement control).
std::vector<FingerLoad> step_loads(const Contact& c, double grip_N, double load_N,
                                   std::optional<double> travel_mm) {
    checked("grip_N", grip_N, 0.0, 1e3, true, "N, grip force per fingertip");
    checked("load_N", load_N, 0.0, 1e3, false, "N, total tangential load");
    if (travel_mm) checked("travel_mm", *travel_mm, -1e3, 1e3, false, "mm");
    std::vector<FingerLoad> loads;
    for (const generators::FingerSetup& s : c.setups) {
        FingerLoad f;
        f.normal_force_N = grip_N;
        f.mu = s.mu;
        const Eigen::Vector2d d = generators::load_direction(s);
        f.tangential_force_N = load_N / double(c.setups.size()) * d;
        if (travel_mm) {
            f.displacement_control = true;
            f.travel_mm = *travel_mm * d;
        }
        loads.push_back(f);
    }
    return loads;
}

void bind_sensor(py::module_& m) {
    using generators::Simulator;
    py::class_<Simulator, std::shared_ptr<Simulator>>(m, "Sensor")
        .def(py::init([](std::optional<std::string> path, std::optional<std::string> text,
                         std::string name, std::string cache_dir, std::optional<std::uint64_t> seed,
                         std::optional<int> variant) {
                 Spec spec = one_sensor(read_spec(path, text, name, seed), variant);
                 py::gil_scoped_release release;
                 return std::make_shared<Simulator>(spec, cache_dir);
             }),
             py::arg("path") = py::none(), py::arg("text") = py::none(),
             py::arg("name") = "<text>", py::arg("cache_dir") = "", py::arg("seed") = py::none(),
             py::arg("variant") = py::none())
        .def_property_readonly("name", [](const Simulator& s) { return s.spec().name; })
        .def_property_readonly("seed", [](const Simulator& s) { return s.spec().seed; })
        .def_property_readonly("source", [](const Simulator& s) { return s.spec().source_path.string(); })
        .def_property_readonly("resolved_yaml", [](const Simulator& s) { return s.spec().resolved_yaml; })
        .def_property_readonly("renders", &Simulator::renders)
        .def_property_readonly("images_ready", &Simulator::images_ready)
        .def_property_readonly("cache_dir", [](const Simulator& s) { return s.cache_dir().string(); })
        .def_property_readonly("precompute_s", &Simulator::model_seconds)
        .def_property_readonly("objects", [](const Simulator& s) {
            std::vector<std::string> names;
            for (const auto& o : s.spec().objects) names.push_back(o.name);
            return names;
        })
        .def_property_readonly("fingers", [](const Simulator& s) { return s.spec().fingers.count; })
        .def_property_readonly("image_size", [](const Simulator& s) {
            return std::pair(s.spec().render.height_px, s.spec().render.width_px);
        })
        .def_property_readonly("mesh", [](const Simulator& s) {
            const auto& st = s.model().stats();
            py::dict d;
            d["level"] = s.model().options().mesh_level;
            d["element_order"] = s.model().options().element_order;
            d["nodes"] = st.nodes;
            d["tets"] = st.tets;
            d["contact_candidates"] = st.candidates;
            d["cache"] = st.cache;
            return d;
        })
        .def("marker_rest_positions", [](const Simulator& s, const std::string& layer) {
            return to_numpy(generators::marker_rest_positions(s.model(), layer_index(layer)));
        }, py::arg("layer"))
        .def("prepare_images", [](Simulator& s) {
            generators::LightCacheOutcome outcome;
            {
                py::gil_scoped_release release;
                outcome = s.prepare_renderer();
            }
            py::dict d;
            d["light_cache_s"] = outcome.seconds;
            d["from_file"] = outcome.from_file;
            d["note"] = outcome.note;
            return d;
        });
}

void bind_contact(py::module_& m) {
    py::class_<Contact, std::shared_ptr<Contact>>(m, "Contact")
        .def(py::init(&make_contact), py::arg("sensor"), py::arg("object"), py::arg("mu"),
             py::arg("direction_deg") = py::none())
        .def_property_readonly("object", [](const Contact& c) { return c.object; })
        .def_property_readonly("fingers", [](const Contact& c) {
            std::vector<std::string> names;
            for (const auto& s : c.setups) names.push_back(s.name);
            return names;
        })
        .def_property_readonly("steps", [](const Contact& c) { return c.steps; })
        .def_property_readonly("mu", [](const Contact& c) {
            std::vector<double> mu;
            for (const auto& s : c.setups) mu.push_back(s.mu);
            return mu;
        })
        .def("step", [](Contact& c, double grip_N, double load_N, std::optional<double> travel_mm,
                        double time_s) {
            checked("time_s", time_s, -kInf, kInf, false, "s");
            const std::vector<FingerLoad> loads = step_loads(c, grip_N, load_N, travel_mm);
            {
                py::gil_scoped_release release;
                c.step(loads);
            }
            return c.frame(loads, grip_N, load_N, travel_mm.value_or(0.0), time_s);
        }, py::arg("grip_N"), py::arg("load_N") = 0.0, py::arg("travel_mm") = py::none(),
           py::arg("time_s") = 0.0)
        .def("reset", [](Contact& c) {
            for (auto& f : c.fingers) f.reset();
            c.steps = 0;
        });
}

void bind_trials(py::module_& m) {
    py::class_<Trials, std::shared_ptr<Trials>>(m, "Trials")
        .def(py::init([](const std::shared_ptr<generators::Simulator>& sim) {
                 return std::make_shared<Trials>(sim);
             }),
             py::arg("sensor"))
        .def("__len__", [](const Trials& t) { return t.plan.trials.size(); })
        .def("frames", [](const Trials& t, int k) { return t.plan.trials.at(std::size_t(k)).frames.size(); })
        .def("info", &trial_info, py::arg("index"))
        .def("run", [](const std::shared_ptr<Trials>& t, int k) {
            if (k < 0 || k >= int(t->plan.trials.size()))
                throw py::index_error("trial " + std::to_string(k) + ": the plan has " +
                                      std::to_string(t->plan.trials.size()) + " trials");
            return std::make_shared<TrialFrames>(t, k);
        }, py::arg("index"));
    py::class_<TrialFrames, std::shared_ptr<TrialFrames>>(m, "TrialFrames")
        .def("__iter__", [](const std::shared_ptr<TrialFrames>& t) { return t; })
        .def("__len__", [](const TrialFrames& t) { return t.run.plan().frames.size(); })
        .def("__next__", [](TrialFrames& t) {
            if (t.run.done()) throw py::stop_iteration();
            std::shared_ptr<Frame> frame;
            {
                py::gil_scoped_release release;
                frame = t.next();
            }
            return frame;
        });
}

} // namespace

} // namespace chromasim::python

PYBIND11_MODULE(_core, m) {
    using namespace chromasim;
    namespace py = pybind11;
    m.doc() = "chromasim's compiled core: use the chromasim package (chromasim/sim.py).";
    m.attr("__version__") = CHROMASIM_VERSION;
    m.attr("build") = CHROMASIM_BUILD;
    // A spec's mistake: a ValueError whose message has file:line:col, key, value, what is allowed.
    py::register_exception<generators::SpecError>(m, "SpecError", PyExc_ValueError);
    m.def("default_cache_dir", [] { return generators::default_cache_dir().string(); });
    python::bind_frame(m);
    python::bind_sensor(m);
    python::bind_contact(m);
    python::bind_trials(m);
}
