#pragma once
/// The contact and stick areas of a frame, measured on the deformed outer surface between the
/// nodes, not counted node by node.
///
/// Why: on the default mesh the contact nodes sit about 0.9 mm apart, and a quadratic face's
/// corner nodes carry no force under Goodman's node contact, so the summed tributary areas of
/// the nodes in contact fell 12 to 19 % short of CalculiX and moved in steps of a whole ring.
///
/// How: near the edge of an elastic contact the gap opens as (s - a)^(3/2) with the distance
/// s from the edge a (Hertz), so phi = gap^(2/3) grows linearly there. phi is taken at the free
/// nodes, its slope fitted over their free neighbours, and extended into the nodes in contact,
/// where it turns negative. On each surface triangle the region phi <= 0 (phi linear) is the
/// contact; inside it, the part nearer the sticking nodes (the midpoint rule) is the stick area.
/// A free node whose neighbours all touch (a quadratic face's corner inside the patch) counts
/// as in contact. No parameter is fitted; docs/VALIDATION.md compares it with CalculiX.
#include "mechanics/contact.hpp"
#include "mechanics/tet_mesh.hpp"

#include <vector>

namespace chromasim::mechanics {

struct ContactAreas {
    double contact_mm2 = 0.0; ///< deformed area in contact
    double stick_mm2 = 0.0;   ///< its part that sticks (<= contact_mm2)
};

class ContactAreaMeter {
public:
    /// `F`: the candidates' outer triangles (indices into the n candidates).
    ContactAreaMeter(const Triangles& F, int n);

    /// `x`: the candidates' deformed positions (n x 3); `contact`: the frame's solution (its
    /// state and gap_mm per candidate).
    ContactAreas measure(const Points& x, const ContactSolution& contact) const;

private:
    Triangles m_F;
    std::vector<std::vector<int>> m_neighbours; ///< per candidate, along the triangles' edges

    /// phi = gap^(2/3) at the free nodes, and its extension (<= 0) into the closed ones.
    Eigen::VectorXd level(const Points& x, const Eigen::VectorXd& gap,
                          const std::vector<char>& closed) const;
    /// phi's slope at free node j, fitted over its free neighbours and theirs (zero if too few).
    Eigen::Vector3d slope(const Points& x, const Eigen::VectorXd& phi,
                          const std::vector<char>& closed, int j) const;
};

} // namespace chromasim::mechanics
