// A solve's checkpoint, DIR/checkpoint.bin: the rows of each form-factor pass made so far (ray-cast
// rows, or blocks of analytic ones)
// (CastCheckpoint, form_factors.h), tied to what they depend on: the scene file, the solve's settings
// and this program's build. Written atomically (a kill leaves the older file or the newer, never half
// of one), by the leader under mpirun, at least every 30 s of casting and at each pass's end, once
// the solve has run 2 s (a quicker one is quicker to run again, and leaves nothing behind). `solve
// --resume` reads it and casts only the rows it lacks; every row is made from its own seeded stream,
// so the result equals an uninterrupted solve's bit for bit. What a resume makes again: the meshing,
// and the stages after the last saved pass (specular paths, iterations, vertex values: seconds on
// the scenes measured, docs/distributed.md).
#pragma once

#include <string>
#include <vector>

#include "solver/radiosity/form_factors.h"
#include "solver/solve.h"

namespace penumbra {

class SolveCheckpoint : public CastCheckpoint {
public:
    // `path`: DIR/checkpoint.bin; `identity`: checkpointIdentity(...).
    SolveCheckpoint(std::string path, std::string identity);
    // The saved passes of a killed run, as read from the file (under mpirun, sent by the leader).
    // Throws Error naming the file and what differs when it was made for another scene, other
    // settings or another build of penumbra, or when it is damaged.
    void resume(const std::string& bytes);
    // What the leader sends the other ranks after resume(): the file's passes, those in row blocks
    // cut to their tag (each rank has its own rows).
    std::string shareable() const;
    // Rank r > 0's own file (row blocks: each rank's rows), DIR/checkpoint.bin.rank-R, as read by it;
    // refused as resume() refuses.
    std::string ownPath() const;
    void resumeOwn(const std::string& bytes);
    int beginPass() override;
    const std::string& savedRows(int pass) const override;
    bool due() const override;
    void save(int pass, std::string rows) override;
    const std::string& ownRows(int pass) const override;
    bool writesNow() const override;
    void saveOwn(int pass, const std::string& head, const char* rows, size_t rowBytes) override;
    void forget(int pass) override;
    // The solve is over (written, or failed with an error): the files go.
    void remove();
    int passesResumed() const { return int(saved_.size()); }

private:
    std::vector<std::string> parse(const std::string& bytes, const std::string& path) const;
    // The file's bytes up to the passes (magic, identity, the count of passes).
    std::string fileHead(size_t passes) const;
    std::string path_, identity_;
    std::vector<std::string> saved_;  // per pass, its rows
    std::vector<std::string> own_;    // rank r > 0, row blocks: per pass, this rank's rows
    int next_ = 0;
    int saves_ = 0;
    double lastSave_, started_;
};

// What a checkpoint's rows depend on, one "name: value" per line: the format, this build of
// penumbra, the scene file's fingerprint, and every setting of the solve (as report.json has them)
// with its seed.
std::string checkpointIdentity(uint64_t sceneFingerprint, const SolveOptions& options);

}  // namespace penumbra
