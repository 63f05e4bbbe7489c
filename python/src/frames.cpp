#include "python/src/frames.hpp"

#include "generators/io/image_io.hpp"
#include "generators/output/label_cells.hpp"

#include <pybind11/stl.h>

#include <algorithm>
#include <cstring>
#include <string_view>

namespace chromasim::python {

namespace {

/// The index of finger `name` in `frame`, else ValueError naming the frame's fingers.
int finger_index(const Frame& frame, const std::string& name) {
    const auto it = std::find(frame.finger_names.begin(), frame.finger_names.end(), name);
    if (it != frame.finger_names.end()) return int(it - frame.finger_names.begin());
    std::string names;
    for (const std::string& n : frame.finger_names)
        names += (names.empty() ? "" : ", ") + n;
    throw py::value_error("finger '" + name + "': this frame's fingertips are " + names);
}

/// The frame's labels.csv columns, without the image paths (a frame through the API has none).
py::dict labels_dict(const Frame& frame) {
    py::dict d;
    for (const auto& [name, cell] : generators::label_cells(frame.labels)) {
        const std::string_view n = name;
        if (n.ends_with("_image") || n.ends_with("_exr")) continue;
        std::visit([&](const auto& v) { d[py::str(name)] = v; }, cell);
    }
    return d;
}

/// The grasp's Gamma (chromasim.data.Dataset.grasp_gamma): the fingertips' gamma weighted by
/// their frictional strength mu f_n, in [0, 1].
double grasp_gamma(const Frame& frame) {
    double strength = 0.0, margin = 0.0;
    for (const generators::LabelRow& r : frame.labels.fingers) {
        const double s = r.mu * r.normal_force_N;
        strength += s;
        margin += s * r.gamma;
    }
    return strength > 0.0 ? std::clamp(margin / strength, 0.0, 1.0) : 0.0;
}

py::dict markers(const Frame& frame, const std::string& finger) {
    const int f = finger_index(frame, finger);
    const mechanics::FrameResult& r = frame.fingers[std::size_t(f)]->result;
    if (r.marker_points_mm.rows() == 0)
        throw py::value_error("markers: this sensor's spec computes no markers (set "
                              "outputs.markers: true, or outputs.images: true)");
    py::dict d;
    d["inner"] = to_numpy(generators::marker_displacements(frame.sim->model(), r, 0));
    d["outer"] = to_numpy(generators::marker_displacements(frame.sim->model(), r, 1));
    return d;
}

py::array_t<double> strain(const Frame& frame, const std::string& finger) {
    const int f = finger_index(frame, finger);
    const mechanics::StrainGrid& g = frame.fingers[std::size_t(f)]->result.strain;
    if (g.eps_xx.empty())
        throw py::value_error("strain: this sensor's spec computes no strain (set "
                              "outputs.strain: true)");
    py::array_t<double> a({g.ny, g.nx});
    std::memcpy(a.mutable_data(), g.eps_xx.data(), g.eps_xx.size() * sizeof(double));
    return a;
}

py::array image(const Frame& frame, const std::string& finger, const std::string& kind) {
    const int f = finger_index(frame, finger);
    if (kind != "png" && kind != "linear")
        throw py::value_error("kind '" + kind + "': allowed: png (the PNG's 8-bit sRGB, through "
                              "render.sensor when enabled), linear (the noise-free float render)");
    generators::SolvedFrame& solved = *frame.fingers[std::size_t(f)];
    render::Image img;
    {
        py::gil_scoped_release release;
        if (kind == "png")
            img = frame.sim->recorded(
                solved, generators::noise_index(frame.labels.trial, f, frame.labels.frame));
        else
            frame.sim->render(solved);
    }
    const render::Image& out = kind == "png" ? img : *solved.image;
    const std::vector<py::ssize_t> shape{out.height, out.width, 3};
    if (kind == "linear") {
        py::array_t<float> a(shape);
        std::memcpy(a.mutable_data(), out.rgb.data(), out.rgb.size() * sizeof(float));
        return std::move(a);
    }
    const generators::Image8 png = generators::to_srgb8(out);
    py::array_t<std::uint8_t> a(shape);
    std::memcpy(a.mutable_data(), png.data.data(), png.data.size());
    return a;
}

} // namespace

int layer_index(const std::string& layer) {
    if (layer == "inner") return 0;
    if (layer == "outer") return 1;
    throw py::value_error("layer '" + layer + "': allowed: inner, outer");
}

py::array_t<double> to_numpy(const Eigen::MatrixX3d& m) {
    py::array_t<double> a({py::ssize_t(m.rows()), py::ssize_t(3)});
    auto v = a.mutable_unchecked<2>();
    for (Eigen::Index i = 0; i < m.rows(); ++i)
        for (int k = 0; k < 3; ++k)
            v(i, k) = m(i, k);
    return a;
}

void Contact::step(const std::vector<generators::FingerLoad>& loads) {
    reused = generators::step_fingertips(fingers, loads);
    ++steps;
}

std::shared_ptr<Frame> Contact::frame(const std::vector<generators::FingerLoad>& loads,
                                      double grip_N, double load_N, double travel_mm,
                                      double time_s) const {
    auto out = std::make_shared<Frame>();
    out->sim = sim;
    out->labels = {"", 0, steps - 1, time_s, "", object, "", grip_N, load_N, travel_mm, {}};
    generators::FramePlan plan;
    plan.index = steps - 1;
    for (std::size_t f = 0; f < fingers.size(); ++f) {
        const auto& solved = fingers[f].current();
        generators::LabelRow row = generators::label_row(plan, loads[f], solved->result);
        row.phase.clear();
        row.reused = reused[f] != 0;
        out->labels.fingers.push_back(std::move(row));
        out->finger_names.push_back(setups[f].name);
        out->fingers.push_back(solved);
    }
    return out;
}

std::shared_ptr<Frame> TrialFrames::next() {
    auto out = std::make_shared<Frame>();
    out->sim = trials->sim;
    out->labels = run.next();
    for (int f = 0; f < run.fingers(); ++f) {
        out->finger_names.push_back(run.plan().fingers[std::size_t(f)].name);
        out->fingers.push_back(run.frame(f));
    }
    return out;
}

py::dict trial_info(const Trials& trials, int index) {
    const generators::TrialPlan& t = trials.plan.trials.at(std::size_t(index));
    const generators::StageSettings& s = trials.sim->settings();
    py::dict d;
    d["trial"] = t.id;
    d["split"] = t.split;
    d["object"] = s.objects[std::size_t(t.object)].object.name;
    d["friction"] = s.friction_names[std::size_t(t.friction)];
    d["mu"] = t.mu;
    d["grip_N"] = t.grip_N;
    d["load_rate_N_per_s"] = t.rate_N_per_s;
    d["target_load_N"] = t.target_load_N;
    d["frames"] = t.frames.size();
    d["first_slip_frame"] = t.first_slip_frame;
    std::vector<double> mu;
    for (const auto& f : t.fingers) mu.push_back(f.mu);
    d["finger_mu"] = mu;
    return d;
}

void bind_frame(py::module_& m) {
    py::class_<Frame, std::shared_ptr<Frame>>(m, "Frame")
        .def_property_readonly("labels", &labels_dict)
        .def_property_readonly("gamma", &grasp_gamma)
        .def_property_readonly("fingers", [](const Frame& f) { return f.finger_names; })
        .def_property_readonly("trial", [](const Frame& f) { return f.labels.trial; })
        .def_property_readonly("index", [](const Frame& f) { return f.labels.frame; })
        .def_property_readonly("time_s", [](const Frame& f) { return f.labels.time_s; })
        .def_property_readonly("converged", [](const Frame& f) {
            return std::all_of(f.labels.fingers.begin(), f.labels.fingers.end(),
                               [](const generators::LabelRow& r) { return r.converged; });
        })
        .def("markers", &markers, py::arg("finger") = "left")
        .def("strain", &strain, py::arg("finger") = "left")
        .def("image", &image, py::arg("finger") = "left", py::arg("kind") = "png");
}

} // namespace chromasim::python
