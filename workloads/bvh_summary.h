// A BVH's summary as JSON (stats.json's "bvh" section and a trace header's), and the layout it
// describes, so a trace reader can set up the layout its steps' ids map through.
#pragma once

#include <nlohmann/json.hpp>
#include <string>

#include "workloads/bvh.h"
#include "workloads/instances.h"

namespace rtsim {

// Builder, quality figures and layout; `treelet_tables` adds the treelet start tables (a trace
// needs them to replay treelet mode; stats keep only the figures).
nlohmann::json bvh_summary(const Bvh& bvh, bool treelet_tables = false);
// A two-level structure's: the build settings; "levels" 2, the TLAS's figures under "tlas" and
// its sah_cost as the top-level one; node, leaf and byte counts over both levels (instance
// records included); the one layout, with its instance region.
nlohmann::json bvh_summary(const TwoLevelBvh& bvh, bool treelet_tables = false);
// The layout a bvh_summary describes; throws InputError naming `where` if it is incomplete.
BvhLayout layout_from_summary(const nlohmann::json& bvh, const std::string& where);

}  // namespace rtsim
