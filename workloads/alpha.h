// Alpha masks of non-opaque geometry: which candidate hits an any-hit shader accepts. A
// triangle of a non-opaque instance that the ray hits nearer than its best hit so far runs the
// shader; an accepted candidate is committed (and ends an any-hit query), an ignored one lets
// traversal go on, as DXR's IgnoreHit and Vulkan's terminateRay/ignoreIntersection define it.
//
// The masks are cut-outs of foliage and fences without textures: the scenes RTSim reads carry
// no texture coordinates, so "texture space" is each triangle's own barycentric (u, v), the
// coordinates u and v weighting vertices 1 and 2 as the tracer and Embree report them.
#pragma once

#include <cmath>
#include <cstdint>

namespace rtsim {

enum class AlphaPattern : uint8_t {
    None = 0,       // every candidate is accepted (the shader still runs if the instance is
                    // not opaque)
    Triangles = 1,  // per triangle: a seeded fraction `keep` of the triangles is solid, the rest
                    // fully cut out
    Checker = 2,    // in texture space: squares of 1/cells in u and v, alternately solid and
                    // cut out (the square at u = v = 0 solid)
};

struct AlphaMask {
    AlphaPattern pattern = AlphaPattern::None;
    double keep = 0.5;   // Triangles: fraction of triangles that are solid
    uint32_t seed = 1;   // Triangles: which ones
    uint32_t cells = 4;  // Checker: squares per unit of u and of v

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
            default:
                return true;
        }
    }
};

}  // namespace rtsim
