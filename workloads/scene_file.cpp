#include "workloads/scene_file.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <random>
#include <set>
#include <sstream>

#include "workloads/error.h"
#include "workloads/memory_limit.h"
#include "workloads/mesh_cache.h"

namespace rtsim {

namespace {

namespace fs = std::filesystem;
using json = nlohmann::ordered_json;  // meshes keep the order the file gives them

// Reads one file's fields, every error naming the file and the field.
class Reader {
  public:
    explicit Reader(std::string file) : file_(std::move(file)) {}

    [[noreturn]] void fail(const std::string& where, const std::string& what) const {
        throw InputError(fmt::format("{}: {}: {}", file_, where, what));
    }
    void only(const json& j, const std::string& where, const std::set<std::string>& keys) const {
        if (!j.is_object()) fail(where, "expected an object");
        for (const auto& item : j.items())
            if (!keys.count(item.key())) fail(where, fmt::format("unknown field '{}'", item.key()));
    }
    double number(const json& j, const std::string& where) const {
        if (!j.is_number()) fail(where, "expected a number");
        const double v = j.get<double>();
        if (!std::isfinite(v)) fail(where, "expected a finite number");
        return v;
    }
    Vec3 vec3(const json& j, const std::string& where) const {
        if (!j.is_array() || j.size() != 3) fail(where, "expected 3 numbers");
        return {float(number(j[0], where)), float(number(j[1], where)), float(number(j[2], where))};
    }
    uint64_t count(const json& j, const std::string& where, uint64_t most) const {
        if (!j.is_number_integer() || j.get<int64_t>() < 1 || j.get<uint64_t>() > most)
            fail(where, fmt::format("expected an integer from 1 to {}", most));
        return j.get<uint64_t>();
    }
    const std::string& file() const { return file_; }

  private:
    std::string file_;
};

// An alpha mask: {"pattern": "triangles", "keep": 0.5, "seed": 1} or
// {"pattern": "checker", "cells": 4}.
AlphaMask alpha_mask(const Reader& rd, const json& j, const std::string& where) {
    rd.only(j, where, {"pattern", "keep", "seed", "cells"});
    AlphaMask a;
    const std::string pattern = j.value("pattern", std::string());
    if (pattern == "triangles") {
        a.pattern = AlphaPattern::Triangles;
        rd.only(j, where, {"pattern", "keep", "seed"});
        if (j.contains("keep")) {
            a.keep = rd.number(j["keep"], where + ".keep");
            if (a.keep < 0 || a.keep > 1)
                rd.fail(where + ".keep", "expected a fraction from 0 to 1");
        }
        if (j.contains("seed")) a.seed = uint32_t(rd.count(j["seed"], where + ".seed", UINT32_MAX));
    } else if (pattern == "checker") {
        a.pattern = AlphaPattern::Checker;
        rd.only(j, where, {"pattern", "cells"});
        if (j.contains("cells")) a.cells = uint32_t(rd.count(j["cells"], where + ".cells", 4096));
    } else {
        rd.fail(where + ".pattern", "expected \"triangles\" or \"checker\"");
    }
    return a;
}

Affine3x4 translation(Vec3 t) {
    Affine3x4 a;
    a.m[3] = t.x;
    a.m[7] = t.y;
    a.m[11] = t.z;
    return a;
}

Affine3x4 scaling(Vec3 s) {
    Affine3x4 a;
    a.m[0] = s.x;
    a.m[5] = s.y;
    a.m[10] = s.z;
    return a;
}

// Rotation by `degrees` about `axis` (Rodrigues), in double.
Affine3x4 rotation(Vec3 axis, double degrees) {
    const double len =
        std::sqrt(double(axis.x) * axis.x + double(axis.y) * axis.y + double(axis.z) * axis.z);
    const double x = axis.x / len, y = axis.y / len, z = axis.z / len;
    const double r = degrees * 3.14159265358979323846 / 180.0, c = std::cos(r), s = std::sin(r),
                 k = 1 - c;
    Affine3x4 a;
    a.m = {float(c + x * x * k),     float(x * y * k - z * s), float(x * z * k + y * s), 0,
           float(y * x * k + z * s), float(c + y * y * k),     float(y * z * k - x * s), 0,
           float(z * x * k - y * s), float(z * y * k + x * s), float(c + z * z * k),     0};
    return a;
}

// An entry's own placement: "transform", or translate * rotate * scale.
Affine3x4 placement(const Reader& rd, const json& e, const std::string& where) {
    if (e.contains("transform")) {
        for (const char* k : {"translate", "rotate", "scale"})
            if (e.contains(k))
                rd.fail(where, fmt::format("'transform' and '{}' both given; use one", k));
        const json& t = e["transform"];
        if (!t.is_array() || t.size() != 12)
            rd.fail(where + ".transform", "expected 12 numbers (a row-major 3x4 matrix)");
        Affine3x4 a;
        for (size_t i = 0; i < 12; ++i)
            a.m[i] = float(rd.number(t[i], fmt::format("{}.transform[{}]", where, i)));
        return a;
    }
    Affine3x4 a;
    if (e.contains("scale")) {
        const json& s = e["scale"];
        const Vec3 v = s.is_array() ? rd.vec3(s, where + ".scale")
                                    : Vec3(1, 1, 1) * float(rd.number(s, where + ".scale"));
        a = scaling(v);
    }
    if (e.contains("rotate")) {
        const json& r = e["rotate"];
        if (!r.is_array() || r.size() != 4)
            rd.fail(where + ".rotate", "expected [axis x, axis y, axis z, degrees]");
        const Vec3 axis = rd.vec3(json::array({r[0], r[1], r[2]}), where + ".rotate");
        if (axis.x == 0 && axis.y == 0 && axis.z == 0)
            rd.fail(where + ".rotate", "the axis is zero");
        a = compose(rotation(axis, rd.number(r[3], where + ".rotate")), a);
    }
    if (e.contains("translate"))
        a = compose(translation(rd.vec3(e["translate"], where + ".translate")), a);
    return a;
}

}  // namespace

bool is_scene_file(const std::string& spec) {
    std::string ext = fs::path(spec).extension().string();
    for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
    return ext == ".json";
}

InstancedScene load_scene_file(const std::string& path, const std::string& cache_dir) {
    std::error_code ec;
    if (!fs::exists(path, ec)) throw InputError(fmt::format("{}: scene file not found", path));
    std::ifstream in(path);
    std::stringstream text;
    text << in.rdbuf();
    if (!in) throw InputError(fmt::format("{}: cannot read the scene file", path));
    json doc;
    try {
        doc = json::parse(text.str());
    } catch (const json::parse_error& e) {
        // nlohmann's message after its "[json.exception.parse_error.N] " prefix.
        const std::string what = e.what();
        const size_t cut = what.find("] ");
        throw InputError(fmt::format("{}: not valid JSON: {}", path,
                                     cut == std::string::npos ? what : what.substr(cut + 2)));
    }
    const Reader rd(path);
    rd.only(doc, "the file", {"meshes", "instances"});
    if (!doc.contains("meshes") || !doc["meshes"].is_object() || doc["meshes"].empty())
        rd.fail("meshes", "expected an object naming at least one mesh (\"name\": \"file\")");
    if (!doc.contains("instances") || !doc["instances"].is_array() || doc["instances"].empty())
        rd.fail("instances", "expected a list of at least one instance");

    InstancedScene scene;
    scene.name = fs::path(path).filename().string();
    scene.source = path;
    // A named mesh is one mesh placed once, or a mesh file whose nodes share meshes: its meshes
    // placed by its own instances, which the scene file's instances then place as a whole (two
    // levels of instancing folded into one, as DXR's TLAS holds them).
    struct Part {
        uint32_t mesh;
        Affine3x4 placement;
        bool opaque;  // unless the scene file's instance says
    };
    std::map<std::string, std::vector<Part>> parts_of;
    const fs::path folder = fs::path(path).parent_path();
    for (const auto& item : doc["meshes"].items()) {
        const std::string where = "meshes." + item.key();
        // "name": "file", or "name": {"file": "file", "alpha": {...}, "flatten": bool}
        const json* file = &item.value();
        AlphaMask alpha;
        bool flatten = false;
        if (item.value().is_object()) {
            rd.only(item.value(), where, {"file", "alpha", "flatten"});
            if (!item.value().contains("file"))
                rd.fail(where + ".file", "expected a mesh file or builtin:NAME");
            file = &item.value()["file"];
            if (item.value().contains("alpha"))
                alpha = alpha_mask(rd, item.value()["alpha"], where + ".alpha");
            if (item.value().contains("flatten")) {
                if (!item.value()["flatten"].is_boolean())
                    rd.fail(where + ".flatten", "expected true or false");
                flatten = item.value()["flatten"].get<bool>();
            }
        }
        if (!file->is_string()) rd.fail(where, "expected a mesh file or builtin:NAME");
        std::string spec = file->get<std::string>();
        if (spec.rfind("builtin:", 0) != 0 && fs::path(spec).is_relative())
            spec = (folder / spec).string();
        if (is_scene_file(spec)) rd.fail(where, "a scene file cannot be a mesh");
        std::vector<Part>& parts = parts_of[item.key()];
        InstancedScene nested;
        Scene mesh = load_scene_cached(spec, cache_dir, nullptr, flatten ? nullptr : &nested);
        const bool masked = alpha.pattern != AlphaPattern::None;
        if (nested.instances.empty()) {
            parts.push_back({uint32_t(scene.meshes.size()), Affine3x4(), !masked});
            scene.meshes.push_back(std::move(mesh));
            scene.alpha.push_back(alpha);
            continue;
        }
        // The file's own masks (glTF alphaMode MASK) and opaque flags hold unless the entry
        // gives a mask, which then covers all of its meshes.
        const auto first = uint32_t(scene.meshes.size());
        for (uint32_t k = 0; k < nested.meshes.size(); ++k) {
            nested.meshes[k].name = item.key() + "/" + nested.meshes[k].name;
            scene.meshes.push_back(std::move(nested.meshes[k]));
            scene.alpha.push_back(masked ? alpha : nested.mesh_alpha(k));
        }
        for (const Instance& i : nested.instances)
            parts.push_back({first + i.mesh, i.object_to_world, masked ? false : i.opaque});
    }
    scene.drop_alpha_if_none();

    const json& list = doc["instances"];
    for (size_t k = 0; k < list.size(); ++k) {
        const std::string where = fmt::format("instances[{}]", k);
        const json& e = list[k];
        rd.only(e, where,
                {"mesh", "transform", "translate", "rotate", "scale", "mask", "opaque", "grid",
                 "scatter"});
        if (!e.contains("mesh") || !e["mesh"].is_string())
            rd.fail(where + ".mesh", "expected the name of a mesh in 'meshes'");
        const auto m = parts_of.find(e["mesh"].get<std::string>());
        if (m == parts_of.end())
            rd.fail(where + ".mesh",
                    fmt::format("no mesh named '{}' in 'meshes'", e["mesh"].get<std::string>()));
        const std::vector<Part>& parts = m->second;
        Instance base;
        base.object_to_world = placement(rd, e, where);
        if (e.contains("mask")) base.mask = uint8_t(rd.count(e["mask"], where + ".mask", 255));
        // Instances of a masked mesh run its any-hit shader unless the file says opaque.
        const bool opaque_given = e.contains("opaque");
        if (opaque_given) {
            if (!e["opaque"].is_boolean()) rd.fail(where + ".opaque", "expected true or false");
            base.opaque = e["opaque"].get<bool>();
        }
        if (e.contains("grid") && e.contains("scatter"))
            rd.fail(where, "'grid' and 'scatter' both given; use one");
        // Copies of the entry (each one instance per part) are counted and checked against
        // memory before they are made.
        const uint64_t room = (kMaxSceneFileInstances - scene.instances.size()) / parts.size();
        auto reserve = [&](uint64_t copies) {
            const uint64_t made = copies * parts.size();
            check_prepare_memory(path, scene.unique_triangle_count(),
                                 scene.instances.size() + made);
            scene.instances.reserve(scene.instances.size() + made);
        };
        auto place = [&](const Affine3x4& copy_to_world) {
            for (const Part& part : parts) {
                Instance i = base;
                i.mesh = part.mesh;
                i.object_to_world = compose(copy_to_world, part.placement);
                if (!opaque_given) i.opaque = part.opaque;
                scene.instances.push_back(i);
            }
        };
        if (e.contains("grid")) {
            const json& g = e["grid"];
            rd.only(g, where + ".grid", {"count", "spacing"});
            if (!g.contains("count") || !g["count"].is_array() || g["count"].size() != 3)
                rd.fail(where + ".grid.count", "expected 3 positive integers");
            uint64_t n[3];
            for (int a = 0; a < 3; ++a) n[a] = rd.count(g["count"][a], where + ".grid.count", room);
            if (n[0] * n[1] * n[2] > room)
                rd.fail(where + ".grid.count",
                        fmt::format("{} copies of {} instance(s): more than {} instances in "
                                    "the file",
                                    n[0] * n[1] * n[2], parts.size(), kMaxSceneFileInstances));
            if (!g.contains("spacing")) rd.fail(where + ".grid.spacing", "missing");
            const Vec3 d = rd.vec3(g["spacing"], where + ".grid.spacing");
            reserve(n[0] * n[1] * n[2]);
            for (uint64_t z = 0; z < n[2]; ++z)
                for (uint64_t y = 0; y < n[1]; ++y)
                    for (uint64_t x = 0; x < n[0]; ++x) {
                        place(compose(
                            translation(Vec3(d.x * float(x), d.y * float(y), d.z * float(z))),
                            base.object_to_world));
                    }
        } else if (e.contains("scatter")) {
            const json& s = e["scatter"];
            rd.only(s, where + ".scatter", {"count", "seed", "min", "max", "scale", "rotate_y"});
            if (!s.contains("count")) rd.fail(where + ".scatter.count", "missing");
            const uint64_t n = rd.count(s["count"], where + ".scatter.count", room);
            const uint64_t seed =
                s.contains("seed") ? rd.count(s["seed"], where + ".scatter.seed", UINT32_MAX) : 1;
            if (!s.contains("min") || !s.contains("max"))
                rd.fail(where + ".scatter", "expected 'min' and 'max' corners of the region");
            const Vec3 lo = rd.vec3(s["min"], where + ".scatter.min"),
                       hi = rd.vec3(s["max"], where + ".scatter.max");
            if (lo.x > hi.x || lo.y > hi.y || lo.z > hi.z)
                rd.fail(where + ".scatter", "'min' exceeds 'max'");
            double scale_lo = 1, scale_hi = 1;
            if (s.contains("scale")) {
                const json& sc = s["scale"];
                if (!sc.is_array() || sc.size() != 2)
                    rd.fail(where + ".scatter.scale", "expected [least, most]");
                scale_lo = rd.number(sc[0], where + ".scatter.scale");
                scale_hi = rd.number(sc[1], where + ".scatter.scale");
                if (!(scale_lo > 0) || scale_hi < scale_lo)
                    rd.fail(where + ".scatter.scale", "expected 0 < least <= most");
            }
            bool yaw = false;
            if (s.contains("rotate_y")) {
                if (!s["rotate_y"].is_boolean())
                    rd.fail(where + ".scatter.rotate_y", "expected true or false");
                yaw = s["rotate_y"].get<bool>();
            }
            // One generator per entry, seeded by its seed: a copy's placement depends on the
            // entry alone, not on the entries before it.
            reserve(n);
            std::mt19937_64 rng(seed);
            std::uniform_real_distribution<double> u01(0.0, 1.0);
            for (uint64_t c = 0; c < n; ++c) {
                const Vec3 p(float(lo.x + (hi.x - lo.x) * u01(rng)),
                             float(lo.y + (hi.y - lo.y) * u01(rng)),
                             float(lo.z + (hi.z - lo.z) * u01(rng)));
                const double angle = 360.0 * u01(rng);
                const float sc = float(scale_lo + (scale_hi - scale_lo) * u01(rng));
                Affine3x4 copy = scaling(Vec3(sc, sc, sc));
                if (yaw) copy = compose(rotation(Vec3(0, 1, 0), angle), copy);
                place(compose(translation(p), compose(copy, base.object_to_world)));
            }
        } else {
            reserve(1);
            place(base.object_to_world);
        }
    }
    scene.validate();
    return scene;
}

}  // namespace rtsim
