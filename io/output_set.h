// A run's output files, which appear together or not at all. They are written into a staging folder
// beside them (DIR/.penumbra-staging-PID), and commit() moves them into place: any older file of the
// same name first aside into the staging folder, then the new one in; should a move fail, the new
// files are taken back out and the older ones put back. The folder then holds the older set or the
// new one, never a mix of two runs' files. Until commit, a failure, the set's destruction, or SIGINT
// or SIGTERM (the handler installSignalCleanup sets up: the run then exits with 128 + the signal)
// leave nothing new behind: the staged files go, the staging folder, and DIR too when this run made
// it. A lock (DIR/.penumbra.lock, flock) held from construction to destruction keeps a second run
// from writing into the same folder meanwhile; it is removed with the set.
#pragma once

#include <string>
#include <vector>

#include "core/error.h"

namespace penumbra {

class OutputSet {
public:
    // `dir`: where the outputs go, made if missing; `names`: the files the run will write there.
    // Throws Error naming the folder or file if the folder cannot be made or written, another run is
    // writing there, or one of the names is taken by something other than a file (a folder called
    // report.json): a run builds its set before any work, so a bad --out costs nothing.
    // `lockName`: the lock file's name in the folder (render's is per image, so that renders of
    // different images into one folder run side by side).
    OutputSet(const std::string& dir, const std::vector<std::string>& names,
              const std::string& lockName = ".penumbra.lock");
    ~OutputSet();
    OutputSet(const OutputSet&) = delete;
    OutputSet& operator=(const OutputSet&) = delete;

    // Where to write the output `name` (one of the names) until commit.
    std::string staged(const std::string& name);
    // Writes the output `name` by write(staged path); an Error it throws names the final path.
    template <typename Write>
    void write(const std::string& name, Write&& write) {
        try {
            write(staged(name));
        } catch (const Error& e) {
            throw Error(inFinalFolder(e.what()));
        }
    }
    // Moves every staged file into place, as above; throws Error if it cannot (nothing new is left).
    void commit();

private:
    void discard() noexcept;
    std::string inFinalFolder(std::string message) const;  // the staging folder's paths as the final ones
    std::string dir_, staging_, lock_;
    std::vector<std::string> names_, made_;  // made_: the folders this run created, outermost first
    std::vector<int> slots_;                 // its paths in the signal handler's list
    int lockFd_ = -1;
    bool committed_ = false;
};

// SIGINT and SIGTERM remove every output set's staged files (and the writers' temporaries of them),
// then exit with 128 + the signal. Once, at start.
void installSignalCleanup();

// Fault injection, for the tests: with PENUMBRA_FAIL_AT=n in the environment, the n-th write or
// rename of the run (each writer and each move counts one) fails as a full disk would, with an
// Error naming `what`.
void faultPoint(const std::string& what);

}  // namespace penumbra
