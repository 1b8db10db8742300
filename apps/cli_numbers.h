// Numbers and lists on the command line, shared by the programs and fuzzed on their own
// (tests/fuzz/fuzz_cli_numbers.cpp): "a,b,c" lists (raw2vdb --dims/--spacing/--origin/--clamp) and
// memory sizes (vdb_isosimp --max-memory). Header-only, no dependencies beyond the standard library.
#pragma once
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <sstream>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

namespace vdb_isosimp {

// A malformed option value; what() names the option.
struct CliUsageError : std::runtime_error {
    using std::runtime_error::runtime_error;
};

// "a,b,c" (or "AxBxC" when allowX, for sizes) -> exactly n numbers. T is double or uint64_t (no
// sign allowed). Blanks around each number are accepted; anything else throws CliUsageError.
template <typename T>
std::vector<T> parseNumberList(const std::string& option, const std::string& text, std::size_t n, bool allowX)
{
    static_assert(std::is_same_v<T, double> || std::is_same_v<T, uint64_t>, "double or uint64_t");
    const auto bad = [&] {
        return CliUsageError(option + ": '" + text + "' is not a list of " + std::to_string(n) + " numbers");
    };
    std::string s = text;
    if (allowX)
        for (char& c : s)
            if (c == 'x' || c == 'X') c = ',';
    if (!s.empty() && s.back() == ',') throw bad();  // getline would drop the empty last item
    std::vector<T> out;
    std::stringstream ss(s);
    std::string part;
    while (std::getline(ss, part, ',')) {
        std::size_t b = 0, e = part.size();
        while (b < e && std::isspace(static_cast<unsigned char>(part[b]))) ++b;
        while (e > b && std::isspace(static_cast<unsigned char>(part[e - 1]))) --e;
        const std::string t = part.substr(b, e - b);
        if (t.empty() || std::memchr(t.data(), '\0', t.size())) throw bad();
        char* end = nullptr;
        errno = 0;
        T v{};
        if constexpr (std::is_same_v<T, double>) {
            v = std::strtod(t.c_str(), &end);
        } else {
            if (!std::isdigit(static_cast<unsigned char>(t[0]))) throw bad();
            const unsigned long long u = std::strtoull(t.c_str(), &end, 10);
            if (errno == ERANGE) throw CliUsageError(option + ": '" + t + "' is too large");
            v = uint64_t(u);
        }
        if (end != t.c_str() + t.size()) throw bad();
        out.push_back(v);
        if (out.size() > n) break;
    }
    if (out.size() != n)
        throw CliUsageError(option + ": expected " + std::to_string(n) + " comma-separated numbers, got '" + text + "'");
    return out;
}

// A memory size: a non-negative number with an optional unit K, M, G or T (powers of 1024; "KB",
// "KiB", "g" ... accepted, case-insensitive), blanks allowed around. False on anything else or when
// it does not fit in 64 bits. "0" means no limit to the callers.
inline bool parseMemorySize(const std::string& text, uint64_t& bytes)
{
    std::size_t i = 0, n = text.size();
    while (i < n && std::isspace(static_cast<unsigned char>(text[i]))) ++i;
    while (n > i && std::isspace(static_cast<unsigned char>(text[n - 1]))) --n;
    std::size_t j = i;
    int dots = 0;
    while (j < n && (std::isdigit(static_cast<unsigned char>(text[j])) || text[j] == '.')) dots += text[j++] == '.';
    const std::string number = text.substr(i, j - i);
    if (number.empty() || dots > 1 || number == ".") return false;
    std::string unit;
    for (std::size_t k = j; k < n; ++k) unit += char(std::toupper(static_cast<unsigned char>(text[k])));
    double scale = 1;
    if (!unit.empty() && unit != "B") {
        static const char units[] = "KMGT";
        const char* p = std::strchr(units, unit[0]);
        const std::string rest = unit.substr(1);
        if (!p || unit[0] == '\0' || !(rest.empty() || rest == "B" || rest == "IB")) return false;
        scale = std::pow(1024.0, double(p - units + 1));
    }
    const double v = std::strtod(number.c_str(), nullptr) * scale;
    if (!std::isfinite(v) || v < 0 || v >= 18446744073709549568.0) return false;
    bytes = uint64_t(v);
    return true;
}

} // namespace vdb_isosimp
