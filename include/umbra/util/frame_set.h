#pragma once
// Frame numbers chosen on the command line (`--frames SPEC`) and the
// frame-number patterns of file names (`shot.####.rib`, `out.%04d.tif`).

#include <string>
#include <vector>

namespace umbra {

/// A set of frame numbers: the union of ranges `first-last` taken every
/// `step`th number. Parsed from `--frames` specs such as
/// `1-100`, `1-100x5`, `3,7,12` and `1-10,20,30-40x2`.
class FrameSet {
public:
    struct Range {
        int first = 0, last = 0, step = 1;
    };

    /// Parses `spec`; false (with `*error` naming what was expected where)
    /// on a malformed spec. Numbers are non-negative integers.
    static bool parse(const std::string& spec, FrameSet* out, std::string* error);

    bool contains(int frame) const;
    /// The numbers in increasing order, each once.
    std::vector<int> numbers() const;
    const std::vector<Range>& ranges() const { return m_ranges; }
    bool empty() const { return m_ranges.empty(); }

private:
    std::vector<Range> m_ranges;
};

/// True when `name` holds a frame-number pattern: a run of '#' (its length
/// is the zero-padded width) or a printf conversion `%d`, `%Nd`, `%0Nd`.
bool hasFramePattern(const std::string& name);
/// `name` with every frame-number pattern replaced by `frame`:
/// `out.####.tif` and `out.%04d.tif` give `out.0012.tif` for frame 12.
/// `%%` stands for one '%'.
std::string expandFramePattern(const std::string& name, int frame);

}  // namespace umbra
