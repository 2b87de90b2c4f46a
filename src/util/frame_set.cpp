#include "umbra/util/frame_set.h"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <climits>

namespace umbra {

namespace {

/// Reads a non-negative integer at s[*pos]; false when there is none or it
/// does not fit an int.
bool readNumber(const std::string& s, size_t* pos, int* out) {
    size_t i = *pos;
    long long v = 0;
    while (i < s.size() && std::isdigit(static_cast<unsigned char>(s[i]))) {
        v = v * 10 + (s[i] - '0');
        if (v > INT_MAX) return false;
        ++i;
    }
    if (i == *pos) return false;
    *out = int(v);
    *pos = i;
    return true;
}

}  // namespace

// spec  := item (',' item)*
// item  := N | N '-' M | N '-' M 'x' STEP      (N <= M, STEP >= 1)
bool FrameSet::parse(const std::string& spec, FrameSet* out, std::string* error) {
    FrameSet set;
    size_t pos = 0;
    auto fail = [&](const std::string& what) {
        *error = fmt::format("\"{}\": {} at character {}; expected a list like 1-100, 1-100x5 (every 5th), "
                             "3,7,12 or 1-10,20,30-40x2",
                             spec, what, pos + 1);
        return false;
    };
    if (spec.empty()) return fail("empty spec");
    while (true) {
        Range r;
        if (!readNumber(spec, &pos, &r.first)) return fail("expected a frame number (0 or more)");
        r.last = r.first;
        if (pos < spec.size() && spec[pos] == '-') {
            ++pos;
            if (!readNumber(spec, &pos, &r.last)) return fail("expected the range's last frame after '-'");
            if (r.last < r.first)
                return fail(fmt::format("the range {}-{} runs backwards (first must be <= last)", r.first, r.last));
            if (pos < spec.size() && spec[pos] == 'x') {
                ++pos;
                if (!readNumber(spec, &pos, &r.step) || r.step < 1)
                    return fail("expected a step of 1 or more after 'x'");
            }
        } else if (pos < spec.size() && spec[pos] == 'x') {
            return fail("a step 'x' needs a range before it (first-last x step)");
        }
        set.m_ranges.push_back(r);
        if (pos == spec.size()) break;
        if (spec[pos] != ',') return fail(fmt::format("unexpected '{}' (expected ',', '-' or 'x')", spec[pos]));
        ++pos;
    }
    *out = std::move(set);
    return true;
}

bool FrameSet::contains(int frame) const {
    for (const Range& r : m_ranges)
        if (frame >= r.first && frame <= r.last && (frame - r.first) % r.step == 0) return true;
    return false;
}

std::vector<int> FrameSet::numbers() const {
    std::vector<int> v;
    for (const Range& r : m_ranges)
        for (long long f = r.first; f <= r.last; f += r.step) v.push_back(int(f));
    std::sort(v.begin(), v.end());
    v.erase(std::unique(v.begin(), v.end()), v.end());
    return v;
}

namespace {

/// The length of a printf frame conversion (`%d`, `%4d`, `%04d`) at s[i]
/// (a '%'), with its width; 0 when there is none.
size_t printfPattern(const std::string& s, size_t i, int* width, bool* zeros) {
    size_t j = i + 1;
    *zeros = j < s.size() && s[j] == '0';
    int w = 0;
    while (j < s.size() && std::isdigit(static_cast<unsigned char>(s[j])) && w < 100) w = w * 10 + (s[j++] - '0');
    if (j < s.size() && s[j] == 'd') {
        *width = w;
        return j + 1 - i;
    }
    return 0;
}

}  // namespace

bool hasFramePattern(const std::string& name) {
    for (size_t i = 0; i < name.size(); ++i) {
        if (name[i] == '#') return true;
        int w;
        bool z;
        if (name[i] == '%' && i + 1 < name.size() && name[i + 1] == '%') {
            ++i;
            continue;
        }
        if (name[i] == '%' && printfPattern(name, i, &w, &z)) return true;
    }
    return false;
}

std::string expandFramePattern(const std::string& name, int frame) {
    std::string out;
    for (size_t i = 0; i < name.size();) {
        if (name[i] == '#') {
            size_t j = i;
            while (j < name.size() && name[j] == '#') ++j;
            out += fmt::format("{:0{}d}", frame, int(j - i));
            i = j;
            continue;
        }
        if (name[i] == '%' && i + 1 < name.size() && name[i + 1] == '%') {
            out += '%';
            i += 2;
            continue;
        }
        int width = 0;
        bool zeros = false;
        if (name[i] == '%') {
            if (size_t n = printfPattern(name, i, &width, &zeros)) {
                out += zeros ? fmt::format("{:0{}d}", frame, width) : fmt::format("{:{}d}", frame, width);
                i += n;
                continue;
            }
        }
        out += name[i++];
    }
    return out;
}

}  // namespace umbra
