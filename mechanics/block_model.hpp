#pragma once
/// An elastic block loaded on its top face (z = 0) by a rigid object: the half-space stand-in
/// for validating contact against Hertz and Cattaneo-Mindlin. Its sides and base either move
/// as the half-space does under the object's total force (Boussinesq and Cerruti, the
/// default: the truncation error falls from O(a / L) to O((a / L)^2)) or are a clamped base
/// with free sides.
#include "mechanics/contact.hpp"
#include "mechanics/elastic_body.hpp"
#include "mechanics/linear_elasticity.hpp"

#include <memory>
#include <string>

namespace chromasim::mechanics {

struct BlockParams {
    /// The block is [-w, w]^2 x [-depth, 0]. With the far field on its boundary, 20 mm (8 to
    /// 11 contact radii) gives the same approach as 40 mm within 0.05 %.
    double half_width_mm = 20.0;
    double depth_mm = 20.0;
    Material material{1.0, 0.49};
    Volumetric volumetric = Volumetric::nodal_average;
    double contact_radius_mm = 3.0; ///< top-face nodes within this radius may touch (a <= 2.43)
    double fine_spacing_mm = 0.3;   ///< grid of extra mesh points near the contact
    double max_volume_mm3 = 40.0;   ///< TetGen -a bound far from the contact
    /// Sides and base follow the half-space's point-force field (half_space.hpp) times the
    /// object's total force, which makes the candidates' compliance C + R S (R: candidate
    /// displacement per unit total force, S: the sum over nodes); false: base clamped, sides
    /// free.
    bool far_field = true;
};

/// Named levels of the block mesh, by the spacing near the contact ("coarse" 0.4 mm,
/// "medium" 0.25 mm, "fine" 0.2 mm). Throws std::invalid_argument otherwise.
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
