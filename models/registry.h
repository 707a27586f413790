// Components registered by name (in the spirit of Ramulator 2 and pbrt's per-component Create):
// replacement policies, treelet schedulers, DRAM models, traversal modes, ... A component is one
// source file that defines it and registers it with RTSIM_REGISTER (below); the config schema
// takes a kind's enum from its registry ("registry": "KIND"), and `rtsim list` prints them all.
//
// Registration runs during static initialisation: the libraries holding components are linked
// whole (CMake's WHOLE_ARCHIVE), so no component is dropped for lack of a reference.
#pragma once

#include <algorithm>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

namespace rtsim {

// What `rtsim list` and the schema see of a component, whatever its kind.
struct ComponentInfo {
    std::string kind;         // "replacement", "treelet_scheduler", ...
    std::string name;         // the config value that selects it
    std::string description;  // one line
    // Config fields it reads beyond its kind's common ones: relative to the section of the field
    // that selects it ("rrpv_bits": l1.replacement = srrip reads l1.rrpv_bits), or a full path
    // when it holds a dot ("ray_buffer.ports").
    std::vector<std::string> params;
};

// Every kind's components, by kind then registration name.
class ComponentIndex {
  public:
    static void add(const ComponentInfo& info) {
        auto& kind = kinds()[info.kind];
        if (std::any_of(kind.begin(), kind.end(),
                        [&](const ComponentInfo& c) { return c.name == info.name; }))
            throw std::logic_error("component registered twice: " + info.kind + " " + info.name);
        kind.push_back(info);
        std::sort(kind.begin(), kind.end(),
                  [](const ComponentInfo& a, const ComponentInfo& b) { return a.name < b.name; });
    }
    static const std::map<std::string, std::vector<ComponentInfo>>& all() { return kinds(); }
    // Names registered for `kind`, sorted; empty for an unknown kind.
    static std::vector<std::string> names(const std::string& kind) {
        std::vector<std::string> out;
        auto it = kinds().find(kind);
        if (it != kinds().end())
            for (const auto& c : it->second) out.push_back(c.name);
        return out;
    }

  private:
    static std::map<std::string, std::vector<ComponentInfo>>& kinds() {
        static std::map<std::string, std::vector<ComponentInfo>> k;  // built on first use
        return k;
    }
};

// The registry of one kind. `Entry` is an aggregate whose first members are `name`,
// `description` and `params` (as in ComponentInfo), then the kind's factory (how to make or bind
// the component); it names its kind as `static constexpr const char* kKind`.
template <typename Entry>
class Registry {
  public:
    static bool add(Entry e) {
        ComponentIndex::add(ComponentInfo{Entry::kKind, e.name, e.description, e.params});
        entries().push_back(std::move(e));
        return true;
    }
    // The entry named `name`, or nullptr.
    static const Entry* find(const std::string& name) {
        for (const Entry& e : entries())
            if (e.name == name) return &e;
        return nullptr;
    }
    // The entry named `name`; std::invalid_argument naming the known ones otherwise (configs
    // are checked against the schema's enum first, so this is a programming error or a test's).
    static const Entry& at(const std::string& name) {
        if (const Entry* e = find(name)) return *e;
        std::string known;
        for (const auto& n : ComponentIndex::names(Entry::kKind))
            known += (known.empty() ? "" : ", ") + n;
        throw std::invalid_argument(std::string("unknown ") + Entry::kKind + " '" + name +
                                    "' (registered: " + known + ")");
    }

  private:
    static std::vector<Entry>& entries() {
        static std::vector<Entry> e;
        return e;
    }
};

#define RTSIM_REGISTRY_CONCAT2(a, b) a##b
#define RTSIM_REGISTRY_CONCAT(a, b) RTSIM_REGISTRY_CONCAT2(a, b)
// RTSIM_REGISTER(EntryType, {"name", "one-line description", {"param", ...}, factory...}):
// registers one component of EntryType's kind.
#define RTSIM_REGISTER(EntryType, ...)                                               \
    namespace {                                                                      \
    [[maybe_unused]] const bool RTSIM_REGISTRY_CONCAT(rtsim_registered_, __LINE__) = \
        ::rtsim::Registry<EntryType>::add(EntryType __VA_ARGS__);                    \
    }

}  // namespace rtsim
