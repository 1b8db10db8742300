// JSON string literal for the reports our programs print (--report, --json): quotes, backslashes and
// control characters escaped. One helper for every program.
#pragma once
#include <cstdio>
#include <string>

namespace vdb_isosimp {

inline std::string jsonString(const std::string& s)
{
    std::string out = "\"";
    for (char c : s) {
        if (c == '"' || c == '\\') out += '\\';
        if (static_cast<unsigned char>(c) < 0x20) {
            char buf[8];
            std::snprintf(buf, sizeof buf, "\\u%04x", c);
            out += buf;
        } else {
            out += c;
        }
    }
    return out + "\"";
}

} // namespace vdb_isosimp
