#include "mechanics/tetgen_adapter.hpp"

#include <tetgen.h>

#include <cstdio>
#include <stdexcept>
#include <vector>

namespace chromasim::mechanics {

std::string tetgen_switches(const TetgenOptions& options) {
    // p: PLC, q: quality, a: max volume, A: region attributes, Y: keep the input surface
    // (no Steiner point on a facet, so every surface node stays on its sphere), Q: quiet.
    char quality[64];
    if (options.min_dihedral_deg > 0)
        std::snprintf(quality, sizeof quality, "q%.4g/%.4g", options.radius_edge_ratio,
                      options.min_dihedral_deg);
    else
        std::snprintf(quality, sizeof quality, "q%.4g", options.radius_edge_ratio);
    char volume[64];
    std::snprintf(volume, sizeof volume, "a%.6g", options.max_volume_mm3);
    return std::string("p") + quality + volume + "A" + (options.preserve_surface ? "Y" : "") +
           (options.extra_points.rows() > 0 ? "i" : "") + (options.sized ? "m" : "") + "Q";
}

namespace {

// tetgenio frees its arrays with delete[] in its destructor: allocate with new[].
void fill_input(const Plc& plc, tetgenio& in) {
    in.firstnumber = 0;
    in.numberofpoints = int(plc.points.rows());
    in.pointlist = new REAL[plc.points.size()];
    for (int i = 0; i < plc.points.rows(); ++i)
        for (int k = 0; k < 3; ++k)
            in.pointlist[3 * i + k] = plc.points(i, k);

    in.numberoffacets = int(plc.facets.size());
    in.facetlist = new tetgenio::facet[plc.facets.size()];
    in.facetmarkerlist = new int[plc.facets.size()];
    for (std::size_t f = 0; f < plc.facets.size(); ++f) {
        tetgenio::facet& facet = in.facetlist[f];
        tetgenio::init(&facet);
        facet.numberofpolygons = 1;
        facet.polygonlist = new tetgenio::polygon[1];
        tetgenio::init(&facet.polygonlist[0]);
        const auto& poly = plc.facets[f];
        facet.polygonlist[0].numberofvertices = int(poly.size());
        facet.polygonlist[0].vertexlist = new int[poly.size()];
        for (std::size_t k = 0; k < poly.size(); ++k)
            facet.polygonlist[0].vertexlist[k] = poly[k];
        in.facetmarkerlist[f] = f < plc.facet_markers.size() ? plc.facet_markers[f] : 0;
    }

    if (!plc.point_size_mm.empty()) { // sizing function at the input points (-m)
        if (plc.point_size_mm.size() != std::size_t(plc.points.rows()))
            throw std::invalid_argument("PLC point sizes: one per point needed");
        in.numberofpointmtrs = 1;
        in.pointmtrlist = new REAL[plc.point_size_mm.size()];
        for (std::size_t i = 0; i < plc.point_size_mm.size(); ++i)
            in.pointmtrlist[i] = plc.point_size_mm[i];
    }
    in.numberofregions = int(plc.regions.size());
    in.regionlist = new REAL[5 * plc.regions.size()];
    for (std::size_t r = 0; r < plc.regions.size(); ++r) {
        for (int k = 0; k < 3; ++k)
            in.regionlist[5 * r + k] = plc.regions[r].seed_mm(k);
        in.regionlist[5 * r + 3] = plc.regions[r].attribute;
        in.regionlist[5 * r + 4] = -1.0; // no regional volume bound (the global -a applies)
    }
}

TetMesh read_output(const tetgenio& out) {
    if (out.numberoftetrahedra == 0 || out.numberofcorners != 4)
        throw std::runtime_error("TetGen produced no linear tetrahedra");
    if (out.numberoftetrahedronattributes < 1)
        throw std::runtime_error("TetGen output carries no region attribute");
    TetMesh mesh;
    mesh.V.resize(out.numberofpoints, 3);
    for (int i = 0; i < out.numberofpoints; ++i)
        for (int k = 0; k < 3; ++k)
            mesh.V(i, k) = out.pointlist[3 * i + k];
    mesh.T.resize(out.numberoftetrahedra, 4);
    mesh.region.resize(out.numberoftetrahedra);
    for (int t = 0; t < out.numberoftetrahedra; ++t) {
        for (int k = 0; k < 4; ++k)
            mesh.T(t, k) = out.tetrahedronlist[4 * t + k];
        mesh.region(t) = int(out.tetrahedronattributelist[t * out.numberoftetrahedronattributes]);
    }
    return mesh;
}

} // namespace

TetMesh tetrahedralize(const Plc& plc, const TetgenOptions& options_in) {
    TetgenOptions options = options_in;
    options.sized = !plc.point_size_mm.empty();
    tetgenio in, out, addin;
    fill_input(plc, in);
    if (options.extra_points.rows() > 0) {
        addin.numberofpoints = int(options.extra_points.rows());
        addin.pointlist = new REAL[options.extra_points.size()];
        for (Eigen::Index i = 0; i < options.extra_points.rows(); ++i)
            for (int k = 0; k < 3; ++k)
                addin.pointlist[3 * i + k] = options.extra_points(i, k);
    }
    std::string switches = tetgen_switches(options);
    try {
        ::tetrahedralize(switches.data(), &in, &out,
                         options.extra_points.rows() > 0 ? &addin : nullptr);
    } catch (int code) {
        // TetGen reports errors by throwing an int (1: out of memory, 2: internal error,
        // 3: self-intersecting input, 4: very small input feature, 5: close facets, 10: ...).
        throw std::runtime_error("TetGen failed (code " + std::to_string(code) +
                                 ") with switches '" + switches +
                                 "': the input surface is invalid or too detailed");
    }
    TetMesh mesh = read_output(out);
    // TetGen's tets are positively oriented in its own convention (the 4th vertex below
    // the first face); flip to ours (positive signed volume) if needed.
    for (int t = 0; t < mesh.T.rows(); ++t)
        if (tet_volume(mesh, t) < 0) std::swap(mesh.T(t, 2), mesh.T(t, 3));
    return mesh;
}

} // namespace chromasim::mechanics
