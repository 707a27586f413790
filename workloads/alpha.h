// Alpha masks of non-opaque geometry: which candidate hits an any-hit shader accepts. A
// triangle of a non-opaque instance that the ray hits nearer than its best hit so far runs the
// shader; an accepted candidate is committed (and ends an any-hit query), an ignored one lets
// traversal go on, as DXR's IgnoreHit and Vulkan's terminateRay/ignoreIntersection define it.
//
// Masks made up for meshes without textures (per triangle, or a checker in each triangle's own
// barycentric (u, v), the coordinates weighting vertices 1 and 2 as the tracer and Embree report
// them), or read from a glTF material with alphaMode MASK: its base colour's alpha (factor times
// texture) at the hit's texture coordinates, against its alphaCutoff.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <memory>
#include <vector>

namespace rtsim {

enum class AlphaPattern : uint8_t {
    None = 0,       // every candidate is accepted (the shader still runs if the instance is
                    // not opaque)
    Triangles = 1,  // per triangle: a seeded fraction `keep` of the triangles is solid, the rest
                    // fully cut out
    Checker = 2,    // in texture space: squares of 1/cells in u and v, alternately solid and
                    // cut out (the square at u = v = 0 solid)
    Texture = 3,    // a material's alpha (AlphaTexture) against its cutoff
};

// glTF's alphaMode MASK: a hit is solid where factor x the texel's alpha >= cutoff. The texel is
// the nearest one to the hit's interpolated texture coordinates, wrapped (glTF's default
// sampler, REPEAT), with texture v running up and image rows down (assimp's convention, which
// flips a glTF file's v on import).
struct AlphaTexture {
    uint32_t width = 0, height = 0;  // 0: no texture, the factor alone
    std::vector<uint8_t> alpha;      // width x height, row 0 the image's top
    // Per triangle of the mesh, the texture coordinates (s, t) of its three corners.
    std::vector<std::array<float, 6>> corner_st;
    float factor = 1.0f;  // baseColorFactor's alpha
    float cutoff = 0.5f;  // alphaCutoff

    bool solid(uint32_t prim, float u, float v) const {
        float a = factor;
        if (width && prim < corner_st.size()) {
            const std::array<float, 6>& c = corner_st[prim];
            const float w = 1.0f - u - v;
            const double s = double(w) * c[0] + double(u) * c[2] + double(v) * c[4];
            const double t = double(w) * c[1] + double(u) * c[3] + double(v) * c[5];
            auto wrap = [](double x, uint32_t n) {
                const double i = std::floor(x * n);
                const double m = i - std::floor(i / n) * n;  // in [0, n)
                return std::min(uint32_t(m), n - 1);
            };
            a *= float(alpha[size_t(wrap(1.0 - t, height)) * width + wrap(s, width)]) / 255.0f;
        }
        return a >= cutoff;
    }
};

struct AlphaMask {
    AlphaPattern pattern = AlphaPattern::None;
    double keep = 0.5;                            // Triangles: fraction of triangles that are solid
    uint32_t seed = 1;                            // Triangles: which ones
    uint32_t cells = 4;                           // Checker: squares per unit of u and of v
    std::shared_ptr<const AlphaTexture> texture;  // Texture (shared: masks are copied freely)

    // Whether the shader accepts a hit on triangle `prim` (the mesh's triangle index) at
    // barycentrics (u, v).
    bool accepts(uint32_t prim, float u, float v) const {
        switch (pattern) {
            case AlphaPattern::Triangles: {
                // SplitMix64's finaliser over the triangle and the seed: independent of the
                // triangle's position in any BVH, so every builder cuts out the same triangles.
                uint64_t z = (uint64_t(seed) << 32 | prim) + 0x9e3779b97f4a7c15ull;
                z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
                z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
                z ^= z >> 31;
                return double(z >> 11) * 0x1.0p-53 < keep;
            }
            case AlphaPattern::Checker: {
                const auto i = int64_t(std::floor(double(u) * cells));
                const auto j = int64_t(std::floor(double(v) * cells));
                return ((i + j) & 1) == 0;
            }
            case AlphaPattern::Texture:
                return !texture || texture->solid(prim, u, v);
            default:
                return true;
        }
    }
};

}  // namespace rtsim
