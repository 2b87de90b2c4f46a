#pragma once
// Procedural primitives (RI spec 3.2 §5.7): a bound standing for geometry
// that is made only when a bucket (or a depth pass) first needs what lies
// in that bound. Splitting the primitive expands it: its RIB is read
// (DelayedReadArchive), asked of a running program (RunProgram) or made
// by a loaded DSO's Subdivide (DynamicLoad), under the attributes and
// transform of the Procedural request, and the primitives it makes are
// the pieces. A bound the view culls is never expanded.

#include "umbra/geometry/primitive.h"
#include "umbra/ri/target.h"
#include "umbra/scene/scene.h"

#include <atomic>
#include <map>
#include <memory>
#include <mutex>
#include <string>

namespace umbra::geometry {

/// What a world's procedurals share while it renders: the world (its
/// options, coordinate systems and lights, which the expanded RIB sees),
/// the camera that measures RenderMan's "detail", the programs RunProgram
/// keeps running, and counters for the statistics. Thread-safe.
class ProceduralContext {
public:
    /// `cameraFromWorld` and `rasterFromCamera` are the camera pass's view,
    /// whichever pass expands a procedural, so the detail a generator is
    /// given (and so what it makes) never depends on which pass or bucket
    /// asked first.
    ProceduralContext(const scene::WorldRecord& world, const Mat4& cameraFromWorld, const Mat4& rasterFromCamera,
                      bool perspective, Diagnostics& diag);
    /// Ends the programs RunProgram started (closing their input).
    ~ProceduralContext();
    ProceduralContext(const ProceduralContext&) = delete;
    ProceduralContext& operator=(const ProceduralContext&) = delete;

    const scene::WorldRecord& world() const { return m_world; }
    Diagnostics& diag() const { return m_diag; }

    /// RenderMan's detail: the raster area, in pixels, of an object-space
    /// bound seen by the camera; infinite when it reaches behind the eye.
    float detail(const Bound3& objectBound, const Mat4& worldFromObject) const;

    /// One RunProgram request: starts `command` (a program and its
    /// arguments, split at blanks; looked for beside the RIB file, then on
    /// the "procedural" search path, then $PATH) unless it is running,
    /// writes `request` ("detail datablock\n") to its input and reads RIB
    /// from its output up to the byte 0xFF. False, with a warning at `loc`,
    /// when the program cannot start, dies, or does not answer within the
    /// time and size budget (the program is then stopped).
    bool runProgram(const std::string& command, const std::string& directory, const std::string& request,
                    const FileLoc& loc, std::string* rib);

    /// Seconds a program may take to answer one request (Option "limits"
    /// "proceduraltime"; default kDefaultProgramSeconds).
    double programSeconds() const { return m_programSeconds; }
    static constexpr double kDefaultProgramSeconds = 60;
    /// Bytes one answer may hold before the program is taken as runaway.
    static constexpr size_t kMaxAnswerBytes = size_t(1) << 30;
    /// Nested procedurals deeper than this are not expanded (an archive
    /// that delays-reads itself).
    static constexpr int kMaxDepth = 64;

    /// Expansions allowed in one frame: the depth limit bounds recursion,
    /// this its breadth (an archive that delays-reads itself twice would
    /// expand 2^64 times), and stays far above what real scenes expand.
    static constexpr int64_t kMaxExpansions = int64_t(1) << 16;
    /// Counts one expansion; false once the frame's are spent (reported once).
    bool chargeExpansion(const FileLoc& loc);

    /// Statistics, summed over passes and threads.
    std::atomic<uint64_t> expanded{0};        // procedurals expanded
    std::atomic<uint64_t> archivesRead{0};    // DelayedReadArchive files read
    std::atomic<uint64_t> programRequests{0}; // RunProgram requests answered
    std::atomic<uint64_t> dsoCalls{0};        // DynamicLoad Subdivide calls
    std::atomic<uint64_t> failures{0};        // expansions that failed (warned)
    std::atomic<uint64_t> primitivesMade{0};  // records the expansions made

private:
    struct Program;
    const scene::WorldRecord& m_world;
    Mat4 m_cameraFromWorld, m_rasterFromCamera;
    bool m_perspective;
    Diagnostics& m_diag;
    double m_programSeconds = kDefaultProgramSeconds;
    std::atomic<int64_t> m_budget;
    std::atomic<bool> m_budgetReported{false};
    std::mutex m_programsMutex;
    std::map<std::string, std::unique_ptr<Program>> m_programs;
};

/// A `Procedural` record: bound() is the request's box (object space), and
/// split() expands it (once: later splits, from other passes, reuse the
/// records made the first time). Never diced.
class Procedural : public Primitive {
public:
    /// The records an expansion made, kept for every pass of the frame
    /// (depth passes and the camera pass expand it once between them).
    struct Expansion;

    Procedural(std::shared_ptr<const scene::PrimitiveRecord> record, std::shared_ptr<ProceduralContext> context,
               std::shared_ptr<Expansion> expansion = nullptr, int depth = 0);
    ~Procedural() override;

    Bound3 bound() const override;
    bool diceable() const override { return false; }
    void split(bool splitU, std::vector<PrimitivePtr>& out) const override;
    /// Never called (not diceable): an empty grid.
    Grid dice(int nu, int nv) const override;

private:
    /// Reads, runs or loads the generator; fills m_expansion once.
    void expand() const;
    /// DynamicLoad: loads the DSO `name` and runs its ConvertParameters
    /// (on `data`), Subdivide (its Ri calls going to `target`) and Free.
    bool runDso(const std::string& name, const std::string& data, const std::string& directory, ri::Target& target,
                Diagnostics& generatorDiag) const;

    std::shared_ptr<ProceduralContext> m_context;
    std::shared_ptr<Expansion> m_expansion;
    int m_depth;
};

/// The RenderMan procedural names umbra expands.
bool isProceduralRecord(const scene::PrimitiveRecord& record);

}  // namespace umbra::geometry
