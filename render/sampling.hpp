#pragma once
/// Random numbers and sampling helpers shared by the integrators: a per-pixel SplitMix64
/// stream (images independent of the thread count), the pixel's stratum grid, cosine-weighted
/// hemisphere directions, Fresnel's equations.
#include <Eigen/Core>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <utility>

namespace chromasim::render::detail {

inline std::uint64_t mix64(std::uint64_t z) {
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

/// SplitMix64 stream for one pixel: cheap, statistically sound, and seeded from (seed, pixel)
/// alone, which makes images independent of thread scheduling.
class PixelRng {
public:
    PixelRng(std::uint64_t seed, std::uint64_t pixel_index)
        : m_state(mix64(seed) ^ mix64(pixel_index + 0x9E3779B97F4A7C15ull)) {}

    /// Uniform in [0, 1) with 53 random bits.
    double uniform() {
        m_state += 0x9E3779B97F4A7C15ull;
        return double(mix64(m_state) >> 11) * 0x1.0p-53;
    }

private:
    std::uint64_t m_state;
};

/// Stratum grid nx x ny == samples: nx is the largest divisor of samples not above
/// sqrt(samples), so every count gives equal strata that tile the pixel (7 -> 1 x 7).
inline std::pair<int, int> strata_grid(int samples) {
    int nx = 1;
    for (int d = 1; d * d <= samples; ++d) {
        if (samples % d == 0) nx = d;
    }
    return {nx, samples / nx};
}

/// The image of i under a pseudo-random permutation of [0, n) chosen by `seed`, without
/// storing the permutation: Kensler's hash-based permutation ("Correlated Multi-Jittered
/// Sampling", Pixar Technical Memo 13-01, 2013), cycle-walking over the next power of two.
/// Pairs the strata of one sampling dimension with another's at random, per pixel.
inline int permute(std::uint32_t i, std::uint32_t n, std::uint32_t seed) {
    std::uint32_t w = n - 1;
    w |= w >> 1, w |= w >> 2, w |= w >> 4, w |= w >> 8, w |= w >> 16;
    do {
        i ^= seed;
        i *= 0xe170893du;
        i ^= seed >> 16;
        i ^= (i & w) >> 4;
        i ^= seed >> 8;
        i *= 0x0929eb3fu;
        i ^= seed >> 23;
        i ^= (i & w) >> 1;
        i *= 1u | seed >> 27;
        i *= 0x6935fa69u;
        i ^= (i & w) >> 11;
        i *= 0x74dcb303u;
        i ^= (i & w) >> 2;
        i *= 0x9e501cc3u;
        i ^= (i & w) >> 2;
        i *= 0xc860a3dfu;
        i &= w;
        i ^= i >> 5;
    } while (i >= n);
    return int((i + seed) % n);
}

/// The hero-wavelength stratum of sample k of a pixel's n: a per-pixel permutation of the
/// strata (`seed`: the pixel's), so that every stratum is taken once and the wavelength strata
/// do not pair up with the position strata along the pixel's rows.
inline int wavelength_stratum(int k, int n, std::uint32_t seed) {
    return permute(std::uint32_t(k), std::uint32_t(n), seed);
}

/// The seeds of a pixel's shadow-ray strata (shadow_uniforms), wavelength permutation and
/// sub-strata of its positions (multi_jittered).
inline std::uint32_t shadow_seed(std::uint64_t seed, std::uint64_t pixel) {
    return std::uint32_t(mix64(seed ^ (pixel << 1)));
}
inline std::uint32_t wavelength_permutation_seed(std::uint64_t seed, std::uint64_t pixel) {
    return std::uint32_t(mix64(seed ^ (pixel << 1) ^ 0xA5A5A5A5A5A5A5A5ull));
}
inline std::uint32_t position_seed(std::uint64_t seed, std::uint64_t pixel) {
    return std::uint32_t(mix64(seed ^ (pixel << 1) ^ 0x3C3C3C3C3C3C3C3Cull));
}

/// A pixel's seeds for its strata: positions, wavelengths, shadow rays. The shadow rays' Sobol
/// points may be shared by a block of pixels (shadow_uniforms): `block` names the block (its
/// Owen scrambling) and `quad` the pixel's place in it; by default a pixel is a block of its
/// own.
struct PixelSeeds {
    PixelSeeds(std::uint64_t seed, std::uint64_t pixel) : PixelSeeds(seed, pixel, pixel, 0) {}
    PixelSeeds(std::uint64_t seed, std::uint64_t pixel, std::uint64_t block, std::uint32_t quad)
        : position(position_seed(seed, pixel)),
          wavelength(wavelength_permutation_seed(seed, pixel)), shadow(shadow_seed(seed, pixel)),
          quad(quad) {
        const std::uint32_t block_seed = shadow_seed(seed, block);
        for (std::size_t d = 0; d < scramble.size(); ++d)
            scramble[d] = std::uint32_t(mix64(block_seed + 0x9E3779B9u * (d + 1)));
    }
    std::uint32_t position, wavelength, shadow;
    std::uint32_t quad;                    ///< the pixel's place in its block (shadow_uniforms)
    std::array<std::uint32_t, 3> scramble; ///< the block's Owen scrambling per dimension
};

/// Sample k's position in the pixel ([0, 1)^2) of its nx x ny: correlated multi-jittered
/// (Kensler, "Correlated Multi-Jittered Sampling", Pixar Technical Memo 13-01, 2013). Cell
/// (k mod nx, k / nx) of the jittered grid, and within it the sub-cell that puts the nx ny
/// samples also one in each of nx ny columns and rows of the pixel (n-rooks): the sub-cells of a
/// column of cells, and those of a row, by one per-pixel permutation each (`seed`: the
/// pixel's). (jx, jy) in [0, 1): the jitter within the sub-cell. Less noise than the jittered
/// grid alone.
inline std::pair<double, double> multi_jittered(int k, int nx, int ny, std::uint32_t seed,
                                                double jx, double jy) {
    const int sx = k % nx, sy = k / nx;
    const int column = permute(std::uint32_t(sx), std::uint32_t(nx), seed * 0xa511e9b3u);
    const int row = permute(std::uint32_t(sy), std::uint32_t(ny), seed * 0x63d83595u);
    return {(sx + (row + jx) / ny) / nx, (sy + (column + jy) / nx) / ny};
}

/// v's 32 bits in reverse order.
inline std::uint32_t reverse_bits(std::uint32_t v) {
    v = (v << 16) | (v >> 16);
    v = ((v & 0x00ff00ffu) << 8) | ((v & 0xff00ff00u) >> 8);
    v = ((v & 0x0f0f0f0fu) << 4) | ((v & 0xf0f0f0f0u) >> 4);
    v = ((v & 0x33333333u) << 2) | ((v & 0xccccccccu) >> 2);
    return ((v & 0x55555555u) << 1) | ((v & 0xaaaaaaaau) >> 1);
}

/// Owen scrambling of the 32-bit fraction v (v / 2^32 in [0, 1)) chosen by `seed`: each bit
/// flipped by a hash of the bits above it (Burley, "Practical Hash-based Owen Scrambling",
/// JCGT 9(4), 2020, the Laine-Karras hash on the reversed bits). It keeps a (t, m, s)-net a
/// net and makes each point uniform in [0, 1).
inline std::uint32_t owen_scramble(std::uint32_t v, std::uint32_t seed) {
    v = reverse_bits(v);
    v ^= v * 0x3d20adeau;
    v += seed;
    v *= (seed >> 16) | 1u;
    v ^= v * 0x05526c56u;
    v ^= v * 0x53a22864u;
    return reverse_bits(v);
}

/// Dimensions 0, 1 and 2 of point i of the Sobol sequence as 32-bit fractions: the van der
/// Corput sequence, then the primitive polynomials x + 1 and x^2 + x + 1 with the initial
/// direction numbers 1 and 1, 3 (Joe and Kuo's). The first 2^m points in dimensions 0 and 1
/// form a (0, m, 2)-net: one point in each of the 2^m boxes of 2^a x 2^(m - a); with
/// dimension 2, a (1, m, 2)-net (two points in each box of twice the area; m = 2 to 6).
inline std::array<std::uint32_t, 3> sobol3(std::uint32_t i) {
    static constexpr std::array<std::uint32_t, 32> dim2 = [] {
        std::array<std::uint32_t, 32> v{};
        v[0] = 1u << 31, v[1] = 3u << 30;
        for (std::size_t q = 2; q < v.size(); ++q)
            v[q] = v[q - 1] ^ v[q - 2] ^ (v[q - 2] >> 2);
        return v;
    }();
    std::array<std::uint32_t, 3> out = {reverse_bits(i), 0u, 0u};
    std::uint32_t v1 = 1u << 31;
    for (std::size_t q = 0; q < 32 && i >> q; ++q, v1 ^= v1 >> 1)
        if (i >> q & 1u) out[1] ^= v1, out[2] ^= dim2[q];
    return out;
}

/// The uniforms (u_led, u1, u2) of the shadow ray of sample k of a pixel's n (the fast
/// integrator: which LED, which point on it): point quad N + permute(k) of the 3-D Sobol
/// sequence, N the power of two at or above n, Owen-scrambled per block and dimension
/// (`seeds`: the pixel's; the permutation is the pixel's own). The point on the LED (u1, u2)
/// takes dimensions 0 and 1, whose strata are the finest, and the samples that pick one LED
/// spread over its area (less noise than u_led stratified alone). The renderer gives the four
/// pixels of a 2 x 2 block one scrambled sequence, quads 0 to 3 row by row: each pixel's
/// points are the first n of a net of N, as alone, and for n a power of two the block's 4 n
/// points are a net four times finer, so the shadow filter, which averages neighbouring
/// pixels' shadow rays, finds them stratified across pixels too.
inline std::array<double, 3> shadow_uniforms(int k, int n, const PixelSeeds& seeds) {
    const std::array<std::uint32_t, 3> x =
        sobol3(seeds.quad * std::bit_ceil(std::uint32_t(n)) +
               std::uint32_t(permute(std::uint32_t(k), std::uint32_t(n), seeds.shadow)));
    const auto scrambled = [&](std::size_t d) {
        return double(owen_scramble(x[d], seeds.scramble[d])) * 0x1.0p-32;
    };
    return {scrambled(2), scrambled(0), scrambled(1)};
}

/// Two unit vectors completing the unit vector `n` to a right-handed orthonormal basis
/// (Duff et al. 2017, "Building an orthonormal basis, revisited").
inline void orthonormal_basis(const Eigen::Vector3d& n, Eigen::Vector3d& b1, Eigen::Vector3d& b2) {
    const double sign = std::copysign(1.0, n.z());
    const double a = -1.0 / (sign + n.z());
    const double b = n.x() * n.y() * a;
    b1 = {1.0 + sign * n.x() * n.x() * a, sign * b, -sign * n.x()};
    b2 = {b, sign + n.y() * n.y() * a, -n.y()};
}

/// Cosine-weighted direction about the unit normal `n` from two uniforms; pdf cos / pi.
inline Eigen::Vector3d cosine_direction(const Eigen::Vector3d& n, double u1, double u2) {
    const double r = std::sqrt(u1), phi = 2.0 * std::numbers::pi * u2;
    Eigen::Vector3d b1, b2;
    orthonormal_basis(n, b1, b2);
    const double z = std::sqrt(std::max(0.0, 1.0 - u1));
    return (r * std::cos(phi) * b1 + r * std::sin(phi) * b2 + z * n).normalized();
}

/// Unpolarised Fresnel reflectance of a smooth dielectric boundary for light arriving at
/// cos_i (> 0) from the side of index n_i onto n_t, eta = n_i / n_t; 1 beyond the critical
/// angle (total internal reflection).
inline double fresnel_dielectric(double cos_i, double eta) {
    cos_i = std::clamp(cos_i, 0.0, 1.0);
    const double sin2_t = eta * eta * (1.0 - cos_i * cos_i);
    if (sin2_t >= 1.0) return 1.0;
    const double cos_t = std::sqrt(1.0 - sin2_t);
    const double rs = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    const double rp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    return 0.5 * (rs * rs + rp * rp);
}

/// The normal turned to face against `direction` (towards where the ray comes from).
inline Eigen::Vector3d facing(const Eigen::Vector3d& normal, const Eigen::Vector3d& direction) {
    return normal.dot(direction) > 0.0 ? Eigen::Vector3d(-normal) : normal;
}

/// Refraction of the unit direction `d` through a boundary with unit normal `n` facing the
/// incoming side (d . n < 0), eta = n_i / n_t; false on total internal reflection.
inline bool refract(const Eigen::Vector3d& d, const Eigen::Vector3d& n, double eta,
                    Eigen::Vector3d& out) {
    const double cos_i = -d.dot(n);
    const double sin2_t = eta * eta * (1.0 - cos_i * cos_i);
    if (sin2_t >= 1.0) return false;
    const double cos_t = std::sqrt(1.0 - sin2_t);
    out = (eta * d + (eta * cos_i - cos_t) * n).normalized();
    return true;
}

} // namespace chromasim::render::detail
