#include "io/output_set.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>

#include "core/error.h"
#include "io/atomic_file.h"

namespace penumbra {
namespace fs = std::filesystem;

namespace {

// The paths a signal must remove, in fixed storage the handler can read without allocating: files
// (unlinked) and folders (removed if empty, the staging folder before the folder it sits in).
struct Slot {
    std::atomic<int> state{0};  // 0 free, 1 being filled, 2 live
    bool folder = false;
    char path[4096];
};
constexpr int kSlots = 256;
Slot g_slots[kSlots];

int remember(const std::string& path, bool folder) {
    if (path.size() >= sizeof(Slot::path)) return -1;
    for (int k = 0; k < kSlots; ++k) {
        int free = 0;
        if (!g_slots[k].state.compare_exchange_strong(free, 1)) continue;
        std::memcpy(g_slots[k].path, path.c_str(), path.size() + 1);
        g_slots[k].folder = folder;
        g_slots[k].state = 2;
        return k;
    }
    return -1;  // more outputs than slots: a signal leaves these few behind
}

extern "C" void removeStagedOnSignal(int signal) {
    for (Slot& s : g_slots)
        if (s.state.load() == 2 && !s.folder) unlink(s.path);
    for (int pass = 0; pass < 3; ++pass)  // nested folders: the inner one empties the outer
        for (Slot& s : g_slots)
            if (s.state.load() == 2 && s.folder) rmdir(s.path);
    _exit(128 + signal);
}

std::string why(int error) { return std::strerror(error); }

}  // namespace

void installSignalCleanup() {
    struct sigaction action {};
    action.sa_handler = removeStagedOnSignal;
    sigemptyset(&action.sa_mask);
    sigaddset(&action.sa_mask, SIGINT);
    sigaddset(&action.sa_mask, SIGTERM);
    sigaction(SIGINT, &action, nullptr);
    sigaction(SIGTERM, &action, nullptr);
}

void faultPoint(const std::string& what) {
    static const long failAt = [] {
        const char* v = std::getenv("PENUMBRA_FAIL_AT");
        return v ? std::atol(v) : 0L;
    }();
    static std::atomic<long> count{0};
    if (failAt > 0 && ++count == failAt)
        throw Error(cat(what, ": cannot write: No space left on device (injected: PENUMBRA_FAIL_AT=", failAt, ")"));
}

namespace {
// Whether process `pid` still runs: it exists and is not a zombie waiting for its parent to read its
// exit (a run killed under `timeout`, whose parent had gone, stayed one here).
bool running(pid_t pid) {
    if (kill(pid, 0) != 0 && errno == ESRCH) return false;
    std::ifstream stat(cat("/proc/", pid, "/stat"));
    std::string text((std::istreambuf_iterator<char>(stat)), std::istreambuf_iterator<char>());
    const size_t paren = text.rfind(')');
    return !(paren != std::string::npos && paren + 2 < text.size() && text[paren + 2] == 'Z');
}
}  // namespace

OutputSet::OutputSet(const std::string& dir, const std::vector<std::string>& names, const std::string& lockName)
    : dir_(dir.empty() ? "." : dir), names_(names) {
    std::error_code ec;
    // The folders to make, outermost first, so that a failed run can take back exactly those.
    std::vector<fs::path> missing;
    for (fs::path p = fs::path(dir_); !p.empty() && !fs::exists(fs::symlink_status(p, ec)); p = p.parent_path()) {
        missing.push_back(p);
        if (p == p.parent_path()) break;
    }
    if (missing.empty() && !fs::is_directory(dir_, ec)) throw Error(cat(dir_, ": exists and is not a folder"));
    std::reverse(missing.begin(), missing.end());
    for (const fs::path& p : missing) {
        if (mkdir(p.c_str(), 0777) != 0) {
            const int error = errno;
            discard();
            throw Error(cat(dir_, ": cannot create the folder: ", why(error)));
        }
        made_.push_back(p.string());
        slots_.push_back(remember(p.string(), true));
    }
    lock_ = (fs::path(dir_) / lockName).string();
    // The lock is the file's inode: a run that opened the file just before its holder removed it
    // would lock a file no longer in the folder while a third run made and locked a new one. So the
    // inode locked must still be the one the name leads to; if not, open the name again.
    for (int attempt = 0;; ++attempt) {
        lockFd_ = open(lock_.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
        if (lockFd_ < 0) {
            const int error = errno;
            discard();
            throw Error(cat(dir_, ": cannot write here: ", why(error)));
        }
        // Test hook (tests/test_outputs.cpp): the file named here, which the test holds locked as a
        // third run would, takes the lock's name between this run's open and its flock.
        if (const char* third = std::getenv("PENUMBRA_TEST_LOCK_SWAP"); third && attempt == 0)
            std::rename(third, lock_.c_str());
        if (flock(lockFd_, LOCK_EX | LOCK_NB) != 0) {
            close(lockFd_);
            lockFd_ = -1;  // another run's lock file: not ours to remove
            lock_.clear();
            discard();
            throw Error(
                cat(dir_, ": another penumbra run is writing its outputs here; wait for it or choose another --out"));
        }
        struct stat held {
        }, named{};
        if (fstat(lockFd_, &held) == 0 && stat(lock_.c_str(), &named) == 0 && held.st_ino == named.st_ino &&
            held.st_dev == named.st_dev)
            break;
        close(lockFd_);
        lockFd_ = -1;
        if (attempt == 100) {
            lock_.clear();
            discard();
            throw Error(cat(dir_, ": its lock file keeps changing: another penumbra run is writing its outputs here"));
        }
    }
    slots_.push_back(remember(lock_, false));
    for (const std::string& name : names_) {
        const fs::path target = fs::path(dir_) / name;
        const fs::file_status st = fs::symlink_status(target, ec);
        if (fs::exists(st) && !fs::is_regular_file(st)) {
            discard();
            throw Error(cat(target.string(), ": exists and is not a file, so it cannot be replaced by the output"));
        }
    }
    // A run killed outright (SIGKILL, a lost host) left its staging folder: its process is gone, so
    // it goes now. (Staging folders of live runs, renders of other images into this folder, stay.)
    for (const fs::directory_entry& e : fs::directory_iterator(dir_, ec)) {
        const std::string name = e.path().filename().string(), prefix = ".penumbra-staging-";
        if (name.rfind(prefix, 0) != 0 || name.size() == prefix.size()) continue;
        const std::string digits = name.substr(prefix.size());
        if (digits.find_first_not_of("0123456789") != std::string::npos || digits.size() > 9) continue;
        const pid_t pid = pid_t(std::stol(digits));
        if (pid != getpid() && !running(pid)) fs::remove_all(e.path(), ec);
    }
    staging_ = (fs::path(dir_) / cat(".penumbra-staging-", getpid())).string();
    if (mkdir(staging_.c_str(), 0777) != 0) {
        const int error = errno;
        staging_.clear();
        discard();
        throw Error(cat(dir_, ": cannot write here: ", why(error)));
    }
    slots_.push_back(remember(staging_, true));
    for (const std::string& name : names_) {
        const std::string path = (fs::path(staging_) / name).string();
        slots_.push_back(remember(path, false));
        slots_.push_back(remember(temporarySibling(path), false));  // the writer's own temporary
    }
}

OutputSet::~OutputSet() { discard(); }

std::string OutputSet::staged(const std::string& name) {
    if (std::find(names_.begin(), names_.end(), name) == names_.end())
        throw Error(cat("internal: output ", name, " was not declared in ", dir_));
    return (fs::path(staging_) / name).string();
}

std::string OutputSet::inFinalFolder(std::string message) const {
    const std::string from = staging_ + "/", to = (fs::path(dir_) / "").string();
    for (size_t at = message.find(from); at != std::string::npos; at = message.find(from, at + to.size()))
        message.replace(at, from.size(), to);
    return message;
}

void OutputSet::commit() {
    // Signals wait while files move: the folder holds one whole set or the other when they land.
    sigset_t block, old;
    sigemptyset(&block);
    sigaddset(&block, SIGINT);
    sigaddset(&block, SIGTERM);
    pthread_sigmask(SIG_BLOCK, &block, &old);
    struct Moved {
        std::string name;
        bool hadOlder;
    };
    std::vector<Moved> moved;
    try {
        for (const std::string& name : names_) {
            const fs::path from = fs::path(staging_) / name, to = fs::path(dir_) / name;
            const fs::path aside = fs::path(staging_) / (".older-" + name);
            std::error_code ec;
            if (!fs::exists(from, ec)) throw Error(cat(to.string(), ": internal: the output was never written"));
            const bool hadOlder = fs::exists(fs::symlink_status(to, ec));
            if (hadOlder) {
                faultPoint(to.string());
                fs::rename(to, aside, ec);
                if (ec) throw Error(cat(to.string(), ": cannot replace: ", ec.message()));
            }
            try {
                faultPoint(to.string());
                fs::rename(from, to, ec);
                if (ec) throw Error(cat(to.string(), ": cannot write: ", ec.message()));
            } catch (...) {
                std::error_code ignored;
                if (hadOlder) fs::rename(aside, to, ignored);  // the older file back
                throw;
            }
            moved.push_back({name, hadOlder});
        }
    } catch (...) {
        // The new files back out, the older ones back in.
        for (auto m = moved.rbegin(); m != moved.rend(); ++m) {
            std::error_code ignored;
            const fs::path to = fs::path(dir_) / m->name;
            fs::rename(to, fs::path(staging_) / m->name, ignored);
            if (m->hadOlder) fs::rename(fs::path(staging_) / (".older-" + m->name), to, ignored);
        }
        pthread_sigmask(SIG_SETMASK, &old, nullptr);
        throw;
    }
    committed_ = true;
    // The set is in place: a signal from here on must not touch it.
    for (int k : slots_)
        if (k >= 0) g_slots[k].state = 0;
    slots_.clear();
    pthread_sigmask(SIG_SETMASK, &old, nullptr);
}

void OutputSet::discard() noexcept {
    std::error_code ec;
    if (!staging_.empty()) {
        for (const std::string& name : names_) {
            const fs::path staged = fs::path(staging_) / name;
            fs::remove(staged, ec);
            fs::remove(temporarySibling(staged.string()), ec);
            // An older file set aside: gone once the new one replaced it; else (its restore failed)
            // kept where it is, rather than lost.
            if (committed_) fs::remove(fs::path(staging_) / (".older-" + name), ec);
        }
        rmdir(staging_.c_str());
        staging_.clear();
    }
    if (lockFd_ >= 0) {
        unlink(lock_.c_str());
        close(lockFd_);
        lockFd_ = -1;
    }
    if (!committed_)
        for (auto p = made_.rbegin(); p != made_.rend(); ++p) rmdir(p->c_str());
    made_.clear();
    for (int k : slots_)
        if (k >= 0) g_slots[k].state = 0;
    slots_.clear();
}

}  // namespace penumbra
