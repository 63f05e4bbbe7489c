#pragma once
/// The spec's table (spec_table.cpp): what the keys are. spec_schema.cpp builds each once and
/// serves them through spec_schema(), spec_lists() and spec_rules().
#include "generators/spec/spec_schema.hpp"

#include <vector>

namespace chromasim::generators::detail {

/// Every leaf key, in manual order; sections and lists are contiguous.
std::vector<SchemaEntry> build_schema();
/// The lists of mappings (objects, friction, splits).
std::vector<SchemaList> build_lists();
/// The cross-key rules, in the order they are checked.
std::vector<SchemaRule> build_rules();

} // namespace chromasim::generators::detail
