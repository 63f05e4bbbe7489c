#pragma once
/// An elastic block clamped at its base, loaded on its top face (z = 0) by a rigid object:
/// the half-space stand-in for validating contact against Hertz and Cattaneo-Mindlin.
#include "mechanics/contact.hpp"
#include "mechanics/elastic_body.hpp"
#include "mechanics/linear_elasticity.hpp"

#include <memory>
#include <string>

namespace chromasim::mechanics {

struct BlockParams {
    double half_width_mm = 40.0; ///< the block is [-w, w]^2 x [-depth, 0]
    double depth_mm = 40.0;
    Material material{1.0, 0.49};
    Volumetric volumetric = Volumetric::nodal_average;
    double contact_radius_mm = 3.5; ///< top-face nodes within this radius may touch
    double fine_spacing_mm = 0.3;   ///< grid of extra mesh points near the contact
    double max_volume_mm3 = 40.0;   ///< TetGen -a bound far from the contact
};

/// Named levels of the block mesh, by the spacing near the contact ("coarse" 0.4 mm,
/// "medium" 0.25 mm, "fine" 0.16 mm). Throws std::invalid_argument otherwise.
BlockParams block_level(const std::string& name);

struct BlockStats {
    int nodes = 0, tets = 0, candidates = 0;
    double mesh_s = 0, precompute_s = 0;
};

class BlockModel {
public:
    explicit BlockModel(const BlockParams& params);
    ~BlockModel();

    /// One frame from rest along `path` (contact.hpp), or from `previous` in path's steps.
    ContactSolution solve(const ContactLoad& load, const ObjectShape& object, const LoadPath& path,
                          const ContactSolution* previous = nullptr,
                          const ContactOptions& options = {}) const;
    /// Candidate positions (mm) and tributary areas (mm^2), in the solution's node order.
    const Points& candidate_positions() const;
    const std::vector<double>& candidate_areas() const;
    const BlockStats& stats() const;

private:
    struct Impl;
    std::unique_ptr<Impl> m_impl;
};

} // namespace chromasim::mechanics
