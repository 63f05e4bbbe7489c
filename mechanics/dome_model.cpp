#include "mechanics/dome_model.hpp"

#include "mechanics/contact_area.hpp"
#include "mechanics/model_cache.hpp"
#include "mechanics/quadratic_tets.hpp"
#include "mechanics/stopwatch.hpp"
#include "mechanics/tetgen_adapter.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <mutex>
#include <numbers>
#include <stdexcept>

namespace chromasim::mechanics {

namespace {

SurfacePatch make_patch(const Triangles& F_global) {
    SurfacePatch patch;
    std::vector<int> local_of;
    patch.F.resize(F_global.rows(), 3);
    for (int f = 0; f < F_global.rows(); ++f)
        for (int k = 0; k < 3; ++k) {
            const int g = F_global(f, k);
            if (g >= int(local_of.size())) local_of.resize(std::size_t(g) + 1, -1);
            if (local_of[g] < 0) {
                local_of[g] = int(patch.nodes.size());
                patch.nodes.push_back(g);
            }
            patch.F(f, k) = local_of[g];
        }
    return patch;
}

} // namespace

struct DomeModel::Impl {
    DomeModelOptions options;
    TetMesh mesh;
    MarkerDiscs markers;
    SurfacePatch coating;
    SurfacePatch inner;          ///< the inner surface facing the air cavity (hollow interior only)
    std::vector<int> candidates; ///< mesh nodes that may touch
    Points candidate_X;          ///< their undeformed positions (mm)
    std::vector<double> candidate_area_mm2;
    std::vector<bool> candidate_edge;   ///< in the outermost band of the candidate cap
    Triangles candidate_F;              ///< outer triangles among the candidates (local ids)
    std::unique_ptr<ContactAreaMeter> area_meter; ///< measures a frame's contact on candidate_F
    mutable std::once_flag strain_once; ///< the strain sampler is built on first request
    mutable std::unique_ptr<SurfaceStrainSampler> strain;
    mutable std::once_flag hyper_once; ///< neo-Hookean energy and marker embedding, on demand
    mutable std::unique_ptr<HyperelasticContact> hyper;
    mutable Embedding marker_embedding;

    void solve_hyperelastic(const ContactLoad& load, const ObjectShape& object,
                            const FrameResult* previous, FrameResult& r) const;
    /// The contact and stick areas and whether the contact reached the candidates' edge.
    void contact_areas(FrameResult& r) const;
    /// The pressure and traction of every candidate (FrameRequest::surface).
    void surface_stresses(FrameResult& r) const;
    /// The observed surfaces and markers from the full field (the neo-Hookean frames).
    void observed_from_field(const FrameRequest& request, FrameResult& r) const;
    /// The observed surfaces and markers from the responses (the linear frames).
    void observed_from_responses(const FrameRequest& request, FrameResult& r) const;
    std::unique_ptr<ElasticBody> body;
    PrecomputeStats stats;

    void build_mesh();
    void derive_from_mesh();
    void find_candidates();
    std::vector<bool> clamped_nodes() const;
    void build_body();
    /// The nodes whose displacement a frame may report: the coating's, then the inner surface's.
    std::vector<int> observed_nodes() const {
        std::vector<int> nodes = coating.nodes;
        nodes.insert(nodes.end(), inner.nodes.begin(), inner.nodes.end());
        return nodes;
    }
    bool load_from_cache(std::uint64_t key);
};

namespace {

/// Material per region attribute - 1: the layers, then the fill (unused unless meshed).
std::vector<Material> material_list(const DomeModelOptions& o) {
    std::vector<Material> list(o.materials.begin(), o.materials.end());
    list.push_back(o.fill);
    return list;
}

/// Everything the cached mesh and responses depend on, as text, hashed into the cache key.
std::uint64_t cache_key(const DomeModelOptions& o) {
    std::string text = "chromasim " CHROMASIM_BUILD " dome-model-cache 3\n";
    char buf[128];
    for (double r : o.dome.radii_mm) {
        std::snprintf(buf, sizeof buf, "radius %.17g\n", r);
        text += buf;
    }
    std::snprintf(buf, sizeof buf, "rings %.17g %d %.17g %d %.17g\n", o.dome.ring_step_deg,
                  o.dome.ring_count, o.dome.marker_radius_mm, o.dome.marker_rim_points,
                  o.dome.marker_thickness_mm);
    text += buf;
    if (o.dome.marker_jitter_mm > 0) {
        std::snprintf(buf, sizeof buf, "marker jitter %.17g %llu\n", o.dome.marker_jitter_mm,
                      static_cast<unsigned long long>(o.dome.marker_jitter_seed));
        text += buf;
    }
    for (const Material& m : o.materials) {
        std::snprintf(buf, sizeof buf, "material %.17g %.17g\n", m.E_MPa, m.nu);
        text += buf;
    }
    const MeshLevel level = mesh_level(o.mesh_level);
    TetgenOptions tg;
    tg.max_volume_mm3 = level.max_volume_mm3;
    std::snprintf(buf, sizeof buf,
                  "mesh %s %.17g %s order %d\nvolumetric %d\ncandidates %.17g\ninterior %d\n",
                  o.mesh_level.c_str(), level.edge_mm, tetgen_switches(tg).c_str(), o.element_order,
                  int(o.volumetric), o.contact_candidate_angle_deg, int(o.interior));
    text += buf;
    if (o.interior == DomeModelOptions::Interior::soft_fill) {
        std::snprintf(buf, sizeof buf, "fill %.17g %.17g\n", o.fill.E_MPa, o.fill.nu);
        text += buf;
    }
    return fnv1a64(text);
}

} // namespace

void DomeModel::Impl::build_mesh() {
    const auto t0 = std::chrono::steady_clock::now();
    const MeshLevel level = mesh_level(options.mesh_level);
    TetgenOptions tg;
    tg.max_volume_mm3 = level.max_volume_mm3;
    mesh = tetrahedralize(
        dome_plc(options.dome, level, options.interior == DomeModelOptions::Interior::soft_fill),
        tg);
    if (options.element_order == 2) make_dome_quadratic(options.dome, mesh);
    stats.mesh_s = seconds_since(t0);
}

void DomeModel::Impl::derive_from_mesh() {
    markers = marker_discs(options.dome, marker_face_margins_mm(options.dome, mesh));
    coating = make_patch(split_faces(mesh, interface_faces(mesh, kCoating, kOuterMarkerLayer)));
    if (options.interior == DomeModelOptions::Interior::hollow) {
        // Boundary faces of the inner layer, less its annulus in the rim plane z = 0.
        const Triangles all = interface_faces(mesh, kInnerMarkerLayer, -1);
        Triangles kept(all.rows(), 3);
        Eigen::Index n = 0;
        for (Eigen::Index f = 0; f < all.rows(); ++f) {
            double z_max = 0.0;
            for (int k = 0; k < 3; ++k)
                z_max = std::max(z_max, std::abs(mesh.V(all(f, k), 2)));
            if (z_max > 1e-9) kept.row(n++) = all.row(f);
        }
        inner = make_patch(split_faces(mesh, kept.topRows(n)));
    }
    stats.nodes = int(mesh.V.rows());
    stats.tets = int(mesh.T.rows());
    find_candidates();
}

void DomeModel::Impl::find_candidates() {
    const double R = options.dome.radii_mm.back();
    const double cos_max = std::cos(options.contact_candidate_angle_deg * std::numbers::pi / 180);
    const double edge_band = 1.5 * mesh_level(options.mesh_level).edge_mm / R; // radians
    const double cos_edge =
        std::cos(options.contact_candidate_angle_deg * std::numbers::pi / 180 - edge_band);
    // Outer surface: boundary faces of the coating off the rim plane; tributary nodal areas.
    const Triangles outer = split_faces(mesh, interface_faces(mesh, kCoating, -1));
    const std::vector<double> area = tributary_areas(
        mesh, outer, [R](const Eigen::Vector3d& p) { return std::abs(p.norm() - R) <= 1e-6; });
    for (int v = 0; v < mesh.V.rows(); ++v) {
        const double cz = mesh.V(v, 2) / R;
        if (area[v] > 0 && cz >= cos_max) {
            candidates.push_back(v);
            candidate_area_mm2.push_back(area[v]);
            candidate_edge.push_back(cz < cos_edge);
        }
    }
    if (candidates.empty()) throw std::runtime_error("no contact candidate nodes on the dome");
    std::vector<int> local(std::size_t(mesh.V.rows()), -1);
    for (std::size_t i = 0; i < candidates.size(); ++i)
        local[std::size_t(candidates[i])] = int(i);
    std::vector<Eigen::Vector3i> tris;
    for (int f = 0; f < outer.rows(); ++f) {
        const Eigen::Vector3i t(local[outer(f, 0)], local[outer(f, 1)], local[outer(f, 2)]);
        if (t.minCoeff() >= 0) tris.push_back(t);
    }
    candidate_F.resize(Eigen::Index(tris.size()), 3);
    for (std::size_t f = 0; f < tris.size(); ++f)
        candidate_F.row(Eigen::Index(f)) = tris[f].transpose();
    candidate_X.resize(Eigen::Index(candidates.size()), 3);
    for (std::size_t i = 0; i < candidates.size(); ++i)
        candidate_X.row(Eigen::Index(i)) = mesh.V.row(candidates[i]);
    stats.candidates = int(candidates.size());
    area_meter = std::make_unique<ContactAreaMeter>(candidate_F, int(candidates.size()));
}

std::vector<bool> DomeModel::Impl::clamped_nodes() const {
    const double r_inner = options.dome.radii_mm.front();
    const bool core = options.interior == DomeModelOptions::Interior::rigid_core;
    // Clamp the rim (every node in the plane z = 0) and, on a rigid core, the inner surface.
    std::vector<bool> clamped(std::size_t(mesh.V.rows()));
    for (int v = 0; v < mesh.V.rows(); ++v)
        clamped[std::size_t(v)] =
            mesh.V(v, 2) <= 1e-9 ||
            (core && std::abs(mesh.V.row(v).norm() - r_inner) <= 1e-9 * r_inner);
    return clamped;
}

bool DomeModel::Impl::load_from_cache(std::uint64_t key) {
    const auto t0 = std::chrono::steady_clock::now();
    std::optional<CachedModel> cached =
        load_cached_model(options.cache_dir, key, &stats.cache_note);
    if (!cached) return false;
    mesh = std::move(cached->mesh);
    derive_from_mesh();
    body = std::make_unique<ElasticBody>(mesh, material_list(options), clamped_nodes(), candidates,
                                         options.volumetric, std::move(cached->responses));
    stats.cache_s = seconds_since(t0);
    stats.cache = "hit";
    return true;
}

void DomeModel::Impl::build_body() {
    body = std::make_unique<ElasticBody>(
        mesh, material_list(options), clamped_nodes(), candidates, observed_nodes(),
        embed(mesh, markers.points, "marker point"), options.volumetric);
    const ElasticBodyStats& b = body->stats();
    stats.assemble_s = b.assemble_s;
    stats.factorize_s = b.factorize_s;
    stats.compliance_s = b.compliance_s;
    stats.free_dofs = b.free_dofs;
}

DomeModel::DomeModel(const DomeModelOptions& options) : m_impl(std::make_unique<Impl>()) {
    Impl& m = *m_impl;
    m.options = options;
    // Quadratic tets: contact at all six nodes of a face has, with the normal problem coupled to
    // the tangential forces, sets with no solution (the active set cycles under sliding).
    m.options.contact.coupled = options.contact.coupled && options.element_order == 1;
    const bool cached = !options.cache_dir.empty();
    const std::uint64_t key = cached ? cache_key(options) : 0;
    if (cached && m.load_from_cache(key)) return;
    m.build_mesh();
    m.derive_from_mesh();
    m.build_body();
    if (!cached) return;
    m.stats.cache = m.stats.cache_note.empty() ? "miss" : "rejected";
    const auto t0 = std::chrono::steady_clock::now();
    std::string problem;
    if (!save_cached_model(options.cache_dir, key, m.mesh, m.body->responses(), &problem))
        m.stats.cache_note += (m.stats.cache_note.empty() ? "" : "; ") + problem;
    m.stats.cache_s = seconds_since(t0);
}

DomeModel::~DomeModel() = default;

namespace {
/// Halvings of a neo-Hookean load step that does not converge, per frame.
constexpr int kMaxCutbacks = 4;

/// `load` with no force and no travel: where a frame from rest starts.
ContactLoad at_rest(ContactLoad load) {
    load.normal_force_N = 0;
    load.tangential_force_N.setZero();
    load.tangential_displacement_mm.setZero();
    return load;
}

/// Whether the load steps a -> b and b -> c change the load by the same (nonzero) amounts.
bool same_increment(const ContactLoad& a, const ContactLoad& b, const ContactLoad& c) {
    const auto delta = [](const ContactLoad& from, const ContactLoad& to) {
        Eigen::Matrix<double, 5, 1> d;
        d << to.normal_force_N - from.normal_force_N,
            to.tangential_force_N - from.tangential_force_N,
            to.tangential_displacement_mm - from.tangential_displacement_mm;
        return d;
    };
    const Eigen::Matrix<double, 5, 1> first = delta(a, b), second = delta(b, c);
    return first.norm() > 0 && (second - first).norm() <= 1e-9 * first.norm();
}
} // namespace

void DomeModel::Impl::solve_hyperelastic(const ContactLoad& load, const ObjectShape& object,
                                         const FrameResult* previous, FrameResult& r) const {
    std::call_once(hyper_once, [this] {
        hyper = std::make_unique<HyperelasticContact>(mesh, material_list(options),
                                                      options.volumetric, *body);
        marker_embedding = embed(mesh, markers.points, "marker point");
    });
    const ContactSolution* last = previous ? &previous->contact : nullptr;
    const Eigen::Index dofs = 3 * mesh.V.rows();
    Eigen::VectorXd u;
    if (previous && previous->node_displacement_mm.rows() == mesh.V.rows())
        u = Eigen::Map<const Eigen::VectorXd>(previous->node_displacement_mm.data(), dofs);
    const Eigen::VectorXd u_start = u;
    std::vector<ContactLoad> targets = load_steps(load, options.load_path, last);
    ContactLoad before = last ? ramp_start(*last, targets[0]) : at_rest(targets[0]);
    // A linear predictor: a step starts from the last one plus the step before it when the load
    // moved the same way; a frame's first step from the previous frame's step (the frames of a
    // trial are near-even increments), spread over this frame's steps.
    Eigen::VectorXd predicted;
    if (u.size() && previous->node_step_mm.rows() == mesh.V.rows())
        predicted = Eigen::Map<const Eigen::VectorXd>(previous->node_step_mm.data(), dofs) /
                    double(targets.size());
    int contact_iterations = 0, cutbacks = 0;
    HyperelasticOptions step_options = options.hyperelastic;
    step_options.first_step = previous ? previous->first_step : 1.0;
    HyperelasticStep step;
    for (std::size_t k = 0; k < targets.size();) {
        const Eigen::Vector2d shift = last ? last->object_displacement_mm : Eigen::Vector2d::Zero();
        const Eigen::VectorXd guess = predicted.size() ? Eigen::VectorXd(u + predicted) : predicted;
        step = hyper->step(object_gap(object, candidate_X, shift), targets[k], last,
                           u.size() ? &u : nullptr, step_options, options.contact,
                           guess.size() ? &guess : nullptr);
        r.material_iterations += step.iterations;
        contact_iterations += step.contact.iterations;
        predicted.resize(0);
        step_options.first_step = step.next_first_step;
        if (!step.converged) { // retried as two halves from the same state
            if (cutbacks++ == kMaxCutbacks) break;
            targets.insert(targets.begin() + std::ptrdiff_t(k),
                           interpolate(before, targets[k], 0.5));
            continue;
        }
        if (k + 1 < targets.size() && same_increment(before, targets[k], targets[k + 1]))
            predicted = step.u - (u.size() ? u : Eigen::VectorXd::Zero(dofs));
        u = step.u;
        r.contact = step.contact;
        last = &r.contact;
        before = targets[k++];
    }
    if (!step.converged) { // the last iterate, flagged
        u = step.u;
        r.contact = step.contact;
        r.contact.converged = false;
        r.contact.status = "hyperelastic_" + step.status;
    } else if (u_start.size()) {
        r.node_step_mm =
            Eigen::Map<const Points>(Eigen::VectorXd(u - u_start).data(), mesh.V.rows(), 3);
    }
    r.contact.iterations = contact_iterations;
    r.min_jacobian = step.min_jacobian;
    r.first_step = step_options.first_step;
    r.node_displacement_mm = Eigen::Map<const Points>(u.data(), mesh.V.rows(), 3);
}

void DomeModel::Impl::contact_areas(FrameResult& r) const {
    for (int j : r.contact.active)
        r.at_candidate_edge = r.at_candidate_edge || candidate_edge[std::size_t(j)];
    if (r.contact.active.empty()) return;
    const ContactAreas areas =
        area_meter->measure(Points(candidate_X + r.contact.displacement_mm), r.contact);
    r.contact_area_mm2 = areas.contact_mm2;
    r.stick_area_mm2 = areas.stick_mm2;
}

void DomeModel::Impl::surface_stresses(FrameResult& r) const {
    const Eigen::Index n = Eigen::Index(candidates.size());
    r.pressure_MPa.resize(n);
    r.traction_MPa.resize(n, 2);
    for (Eigen::Index j = 0; j < n; ++j) {
        const double area = candidate_area_mm2[std::size_t(j)];
        r.pressure_MPa(j) = -r.contact.forces_N(j, 2) / area;
        r.traction_MPa.row(j) = r.contact.forces_N.row(j).head<2>() / area;
    }
}

void DomeModel::Impl::observed_from_field(const FrameRequest& request, FrameResult& r) const {
    const Points& U = r.node_displacement_mm;
    if (request.coating) {
        r.coating_displacement_mm.resize(Eigen::Index(coating.nodes.size()), 3);
        for (std::size_t i = 0; i < coating.nodes.size(); ++i)
            r.coating_displacement_mm.row(Eigen::Index(i)) = U.row(coating.nodes[i]);
    }
    if (request.inner_surface) {
        r.inner_surface_displacement_mm.resize(Eigen::Index(inner.nodes.size()), 3);
        for (std::size_t i = 0; i < inner.nodes.size(); ++i)
            r.inner_surface_displacement_mm.row(Eigen::Index(i)) = U.row(inner.nodes[i]);
    }
    if (request.markers) {
        r.marker_points_mm = markers.points;
        std::array<int, 10> nodes;
        std::array<double, 10> weights;
        for (std::size_t p = 0; p < marker_embedding.tet.size(); ++p) {
            const int count = interpolation_stencil(mesh, marker_embedding.tet[p],
                                                    marker_embedding.weights[p], nodes, weights);
            for (int a = 0; a < count; ++a)
                r.marker_points_mm.row(Eigen::Index(p)) +=
                    weights[std::size_t(a)] * U.row(nodes[std::size_t(a)]);
        }
    }
}

void DomeModel::Impl::observed_from_responses(const FrameRequest& request, FrameResult& r) const {
    if (request.full_field)
        r.node_displacement_mm = body->full_displacement(r.contact.forces_N, r.contact.active);
    if (!request.coating && !request.inner_surface && !request.markers) return;
    const Points u = body->observed_displacement(r.contact.forces_N, r.contact.active);
    const Eigen::Index n_coating = Eigen::Index(coating.nodes.size());
    const Eigen::Index n_inner = Eigen::Index(inner.nodes.size());
    if (request.coating) r.coating_displacement_mm = u.topRows(n_coating);
    if (request.inner_surface) r.inner_surface_displacement_mm = u.middleRows(n_coating, n_inner);
    if (request.markers)
        r.marker_points_mm = markers.points + u.bottomRows(u.rows() - n_coating - n_inner);
}

FrameResult DomeModel::solve(const ContactLoad& load, const FrameRequest& request,
                             const ObjectShape& object, const FrameResult* previous) const {
    const Impl& m = *m_impl;
    FrameResult r;
    const bool hyperelastic = m.options.material == MaterialModel::neo_hookean;
    if (hyperelastic)
        m.solve_hyperelastic(load, object, previous, r);
    else
        r.contact = solve_contact_path(m.body->compliance(), object, m.candidate_X, load,
                                       m.options.load_path, previous ? &previous->contact : nullptr,
                                       m.options.contact);
    m.contact_areas(r);
    if (request.surface) m.surface_stresses(r);
    if (request.strain) {
        std::call_once(m.strain_once, [&m] {
            m.strain = std::make_unique<SurfaceStrainSampler>(m.candidate_X, m.candidate_F,
                                                              m.options.strain_grid);
        });
        r.strain = m.strain->sample(r.contact.displacement_mm);
    }
    if (hyperelastic)
        m.observed_from_field(request, r);
    else
        m.observed_from_responses(request, r);
    return r;
}

const TetMesh& DomeModel::mesh() const {
    return m_impl->mesh;
}
const MarkerDiscs& DomeModel::markers() const {
    return m_impl->markers;
}
const SurfacePatch& DomeModel::coating_surface() const {
    return m_impl->coating;
}
const SurfacePatch& DomeModel::inner_surface() const {
    return m_impl->inner;
}
const PrecomputeStats& DomeModel::stats() const {
    return m_impl->stats;
}
const std::vector<int>& DomeModel::candidate_nodes() const {
    return m_impl->candidates;
}
const std::vector<double>& DomeModel::candidate_areas() const {
    return m_impl->candidate_area_mm2;
}
const Triangles& DomeModel::candidate_triangles() const {
    return m_impl->candidate_F;
}
const DomeModelOptions& DomeModel::options() const {
    return m_impl->options;
}

} // namespace chromasim::mechanics
