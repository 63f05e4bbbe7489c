#pragma once
// The Python API's objects over generators/pipeline/simulator.hpp: a stepped contact, a spec's
// trials, and the frames both give. Plain structs; module.cpp and frames.cpp bind them.
#include "generators/pipeline/simulator.hpp"
#include "generators/plan/plan.hpp"

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <memory>
#include <string>
#include <vector>

namespace chromasim::python {

namespace py = pybind11;

/// One frame of one or two fingertips: its labels and solved fields, and its images on request.
struct Frame {
    std::shared_ptr<generators::Simulator> sim;
    generators::FrameLabels labels;
    std::vector<std::string> finger_names;
    std::vector<std::shared_ptr<generators::SolvedFrame>> fingers;
};

/// One fingertip, or two facing each other, pressed by one spec object; stepped by the caller.
struct Contact {
    explicit Contact(std::shared_ptr<generators::Simulator> s) : sim(std::move(s)) {}
    std::shared_ptr<generators::Simulator> sim;
    std::string object;
    std::vector<generators::FingerSetup> setups;
    std::vector<generators::Fingertip> fingers;
    int steps = 0;
    std::vector<char> reused;
    /// Solves every fingertip's next frame (call without the GIL).
    void step(const std::vector<generators::FingerLoad>& loads);
    /// The frame just solved, labelled.
    std::shared_ptr<Frame> frame(const std::vector<generators::FingerLoad>& loads, double grip_N,
                                 double load_N, double travel_mm, double time_s) const;
};

/// A spec's plan of trials.
struct Trials {
    explicit Trials(std::shared_ptr<generators::Simulator> s)
        : sim(std::move(s)), plan(generators::make_plan(sim->spec())) {}
    std::shared_ptr<generators::Simulator> sim;
    generators::Plan plan;
};

/// One trial of a plan, frame by frame (the plan kept alive by `trials`).
struct TrialFrames {
    TrialFrames(std::shared_ptr<Trials> t, int index)
        : trials(std::move(t)), run(*trials->sim, trials->plan.trials[std::size_t(index)]) {}
    std::shared_ptr<Trials> trials;
    generators::TrialRun run;
    /// Solves the next frame (call without the GIL).
    std::shared_ptr<Frame> next();
};

/// The factors of trial `index` as a dict.
py::dict trial_info(const Trials& trials, int index);
/// "inner" -> 0, "outer" -> 1; else ValueError.
int layer_index(const std::string& layer);
/// An n x 3 matrix as a new numpy array.
py::array_t<double> to_numpy(const Eigen::MatrixX3d& m);

void bind_frame(py::module_& m);

} // namespace chromasim::python
