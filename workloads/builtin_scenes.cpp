// Procedural scenes, so the simulator runs anywhere without a mesh file.
#include <fmt/format.h>
#include <cmath>
#include <map>
#include <utility>

#include "workloads/error.h"
#include "workloads/scene.h"

namespace rtsim {
namespace {

// A rectangle origin + s*u + t*v, s,t in [0,1], split into n x n quads (2 triangles each).
void add_grid(Scene& s, Vec3 origin, Vec3 u, Vec3 v, int n) {
    const auto base = static_cast<uint32_t>(s.vertices.size());
    for (int j = 0; j <= n; ++j)
        for (int i = 0; i <= n; ++i)
            s.vertices.push_back(origin + u * (float(i) / n) + v * (float(j) / n));
    auto idx = [&](int i, int j) { return base + static_cast<uint32_t>(j * (n + 1) + i); };
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
            s.triangles.push_back({idx(i, j), idx(i + 1, j), idx(i + 1, j + 1)});
            s.triangles.push_back({idx(i, j), idx(i + 1, j + 1), idx(i, j + 1)});
        }
}

// Axis-aligned box with its 6 faces split into n x n grids, rotated about y by angle_rad.
void add_box(Scene& s, Vec3 center, Vec3 half, float angle_rad, int n) {
    const size_t first = s.vertices.size();
    const Vec3 c = center;
    const Vec3 h = half;
    add_grid(s, c + Vec3(-h.x, -h.y, h.z), {2 * h.x, 0, 0}, {0, 2 * h.y, 0}, n);   // +z
    add_grid(s, c + Vec3(h.x, -h.y, -h.z), {-2 * h.x, 0, 0}, {0, 2 * h.y, 0}, n);  // -z
    add_grid(s, c + Vec3(h.x, -h.y, h.z), {0, 0, -2 * h.z}, {0, 2 * h.y, 0}, n);   // +x
    add_grid(s, c + Vec3(-h.x, -h.y, -h.z), {0, 0, 2 * h.z}, {0, 2 * h.y, 0}, n);  // -x
    add_grid(s, c + Vec3(-h.x, h.y, h.z), {2 * h.x, 0, 0}, {0, 0, -2 * h.z}, n);   // +y
    add_grid(s, c + Vec3(-h.x, -h.y, -h.z), {2 * h.x, 0, 0}, {0, 0, 2 * h.z}, n);  // -y
    const float cs = std::cos(angle_rad), sn = std::sin(angle_rad);
    for (size_t i = first; i < s.vertices.size(); ++i) {
        Vec3 p = s.vertices[i] - c;
        s.vertices.mutable_at(i) = c + Vec3(cs * p.x + sn * p.z, p.y, -sn * p.x + cs * p.z);
    }
}

// Icosahedron subdivided `levels` times and projected to a sphere: 20 * 4^levels triangles.
void add_icosphere(Scene& s, Vec3 center, float radius, int levels) {
    const float t = (1.0f + std::sqrt(5.0f)) / 2.0f;
    std::vector<Vec3> v = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0},
                           {0, -1, t}, {0, 1, t}, {0, -1, -t}, {0, 1, -t},
                           {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
    for (Vec3& p : v) p = normalize(p);
    std::vector<std::array<uint32_t, 3>> f = {
        {0, 11, 5},  {0, 5, 1},  {0, 1, 7},  {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
        {11, 10, 2}, {10, 7, 6}, {7, 1, 8},  {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
        {3, 8, 9},   {4, 9, 5},  {2, 4, 11}, {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
    for (int l = 0; l < levels; ++l) {
        std::map<std::pair<uint32_t, uint32_t>, uint32_t> mid;
        auto midpoint = [&](uint32_t a, uint32_t b) {
            auto key = std::minmax(a, b);
            auto it = mid.find(key);
            if (it != mid.end()) return it->second;
            v.push_back(normalize((v[a] + v[b]) * 0.5f));
            return mid[key] = static_cast<uint32_t>(v.size() - 1);
        };
        std::vector<std::array<uint32_t, 3>> next;
        next.reserve(f.size() * 4);
        for (auto& tri : f) {
            uint32_t a = midpoint(tri[0], tri[1]), b = midpoint(tri[1], tri[2]),
                     c = midpoint(tri[2], tri[0]);
            next.push_back({tri[0], a, c});
            next.push_back({tri[1], b, a});
            next.push_back({tri[2], c, b});
            next.push_back({a, b, c});
        }
        f.swap(next);
    }
    const auto base = static_cast<uint32_t>(s.vertices.size());
    for (const Vec3& p : v) s.vertices.push_back(center + p * radius);
    for (auto& tri : f) s.triangles.push_back({base + tri[0], base + tri[1], base + tri[2]});
}

Scene cornell() {
    // A 2 x 2 x 2 room open towards +z, two boxes and a finely tessellated sphere (~26k triangles):
    // large flat walls beside dense small triangles, like real scenes.
    Scene s;
    const int n = 16;
    add_grid(s, {-1, 0, 1}, {2, 0, 0}, {0, 0, -2}, n);  // floor
    add_grid(s, {-1, 2, -1}, {2, 0, 0}, {0, 0, 2}, n);  // ceiling
    add_grid(s, {-1, 0, -1}, {2, 0, 0}, {0, 2, 0}, n);  // back
    add_grid(s, {-1, 0, 1}, {0, 0, -2}, {0, 2, 0}, n);  // left
    add_grid(s, {1, 0, -1}, {0, 0, 2}, {0, 2, 0}, n);   // right
    add_box(s, {-0.35f, 0.6f, -0.35f}, {0.3f, 0.6f, 0.3f}, 0.3f, 8);
    add_box(s, {0.4f, 0.3f, 0.35f}, {0.3f, 0.3f, 0.3f}, -0.3f, 8);
    add_icosphere(s, {0.4f, 0.95f, 0.35f}, 0.35f, 5);
    return s;
}

Scene sphere() {
    Scene s;
    add_icosphere(s, {0, 0, 0}, 1.0f, 4);
    return s;
}

}  // namespace

std::vector<std::string> builtin_scene_names() {
    return {"cornell", "sphere"};
}

Scene make_builtin_scene(const std::string& name) {
    Scene s;
    if (name == "cornell")
        s = cornell();
    else if (name == "sphere")
        s = sphere();
    else
        throw InputError(
            fmt::format("builtin:{}: unknown built-in scene (known: cornell, sphere)", name));
    s.name = "builtin:" + name;
    s.source = "builtin";
    return s;
}

}  // namespace rtsim
