// rtsim list: every registered component (replacement policies, treelet schedulers, DRAM models,
// traversal modes, ...) with the config fields that select it, a one-line description and the
// parameters it reads.
#pragma once

#include <map>
#include <string>
#include <vector>

namespace rtsim {

// Per component kind, the schema fields that select one ("l1.replacement", "l2.replacement").
std::map<std::string, std::vector<std::string>> component_selectors();

// Prints the components of `kind` (every kind when empty) as text or JSON; InputError for an
// unknown kind.
int list_command(const std::string& kind, bool as_json);

}  // namespace rtsim
