// Building /bin/sh command lines (sbatch, rsvg-convert) from arbitrary paths.
#pragma once

#include <string>

namespace rtsim {

// `s` as one single-quoted shell word (a quote inside closes, escapes and reopens).
inline std::string shell_quoted(const std::string& s) {
    std::string q = "'";
    for (char ch : s) q += ch == '\'' ? std::string("'\\''") : std::string(1, ch);
    return q + "'";
}

}  // namespace rtsim
