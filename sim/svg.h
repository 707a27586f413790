// What the SVG writers (compare --svg, sweep plots) share.
#pragma once

#include <string>

namespace rtsim {

// Text made safe inside SVG elements and single- or double-quoted attributes.
inline std::string escape_xml(const std::string& t) {
    std::string out;
    for (char ch : t) {
        switch (ch) {
            case '<':
                out += "&lt;";
                break;
            case '>':
                out += "&gt;";
                break;
            case '&':
                out += "&amp;";
                break;
            case '\'':
                out += "&apos;";
                break;
            case '"':
                out += "&quot;";
                break;
            default:
                out += ch;
        }
    }
    return out;
}

}  // namespace rtsim
