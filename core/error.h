// Errors: `Error` for user-facing problems (bad input, refused requests), thrown inside and caught
// once in apps/; `PENUMBRA_CHECK*` for programmer errors, which print both operands.
#pragma once

#include <sstream>
#include <stdexcept>
#include <string>

namespace penumbra {

class Error : public std::runtime_error {
public:
    explicit Error(const std::string& message) : std::runtime_error(message) {}
};

// Builds a message from streamable pieces: throw Error(cat("file ", f, ": ", what)).
template <typename... Parts>
std::string cat(const Parts&... parts) {
    std::ostringstream out;
    (out << ... << parts);
    return out.str();
}

// A number as the shortest text that reads back to it ("1.0000001", not the stream's "1"), for
// messages that compare a value with a limit it barely misses.
std::string exact(double v);

// Whether `text` is, whole, a finite number (strtod alone reads "nan" and "inf", and stops where the
// number does), put into `v`: for option values and the numbers of mesh files.
bool finiteNumber(const std::string& text, double& v);

[[noreturn]] void checkFailed(const char* file, int line, const std::string& what);

}  // namespace penumbra

#define PENUMBRA_CHECK(cond)                                                                 \
    do {                                                                                     \
        if (!(cond)) ::penumbra::checkFailed(__FILE__, __LINE__, "CHECK(" #cond ") failed"); \
    } while (0)

#define PENUMBRA_CHECK_OP(a, op, b)                                                                    \
    do {                                                                                               \
        const auto& check_a_ = (a);                                                                    \
        const auto& check_b_ = (b);                                                                    \
        if (!(check_a_ op check_b_))                                                                   \
            ::penumbra::checkFailed(                                                                   \
                __FILE__, __LINE__,                                                                    \
                ::penumbra::cat("CHECK(" #a " " #op " " #b ") failed: ", check_a_, " vs ", check_b_)); \
    } while (0)

#define PENUMBRA_CHECK_EQ(a, b) PENUMBRA_CHECK_OP(a, ==, b)
#define PENUMBRA_CHECK_LT(a, b) PENUMBRA_CHECK_OP(a, <, b)
#define PENUMBRA_CHECK_LE(a, b) PENUMBRA_CHECK_OP(a, <=, b)
