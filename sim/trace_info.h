// `rtsim trace-info FILE`: what a trace holds, decoded and checked chunk by chunk.
#pragma once

#include <string>

namespace rtsim {

int trace_info_command(const std::string& path, bool as_json);

}  // namespace rtsim
