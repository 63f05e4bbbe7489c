#pragma once
/// labels.csv's columns as one table, so that the file's header, its rows and any other reader
/// of a frame's labels (the Python API) name and give the same values.
#include "generators/output/dataset_writer.hpp"

#include <string>
#include <utility>
#include <variant>
#include <vector>

namespace chromasim::generators {

/// One labels.csv cell: a number (written at 9 significant digits), an integer or text.
using LabelCell = std::variant<double, long, std::string>;

/// A frame's labels.csv cells in column order, each with its column's name: the frame's
/// columns, then each fingertip's, prefixed by its name ("left_gamma").
std::vector<std::pair<std::string, LabelCell>> label_cells(const FrameLabels& frame);

/// The labels.csv header of a dataset with `fingers` fingertips.
std::string labels_header(int fingers);

} // namespace chromasim::generators
