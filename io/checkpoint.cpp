#include "io/checkpoint.h"

#include <unistd.h>

#include <chrono>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <sstream>
#include <string_view>

#include "core/cluster.h"
#include "core/error.h"
#include "core/log.h"
#include "io/atomic_file.h"

namespace penumbra {
namespace {

constexpr char kMagic[8] = {'P', 'N', 'B', 'C', 'K', 'P', '0', '1'};
// Saved when this much casting has passed since the last save: the segments between chances to save
// take at most 10 s (ray_form_factors.cpp, and one row), so no more than 30 s of work is ever lost.
constexpr double kSaveSeconds = 20;
// Nor is a solve's first save made before this much of it has passed: a solve quicker than that is
// quicker to run again, and one interrupted (SIGINT, SIGTERM) leaves nothing at all behind.
constexpr double kFirstSaveSeconds = 2;

double now() { return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count(); }

std::vector<std::string> lines(const std::string& text) {
    std::vector<std::string> out;
    std::istringstream in(text);
    for (std::string line; std::getline(in, line);) out.push_back(line);
    return out;
}

}  // namespace

std::string checkpointIdentity(uint64_t sceneFingerprint, const SolveOptions& options) {
    SolveOptions o = options;
    std::string settings =
        cat("seed=", o.formFactors.seed, " form_factors=", o.formFactors.method, " solver=", o.solver,
            " vertex_radiosity=", o.vertexRadiosity, " gather_only=", o.forSolvedIndirectGather);
    for (const SolveSetting& e : solveSettings(o))
        settings += cat(" ", e.key, "=", std::visit([](auto* v) { return exact(double(*v)); }, e.value));
    return cat("format: 1\nbuild: ", PENUMBRA_BUILD, "\nscene: ", sceneFingerprint, "\nsettings: ", settings, "\n");
}

SolveCheckpoint::SolveCheckpoint(std::string path, std::string identity)
    : path_(std::move(path)), identity_(std::move(identity)), lastSave_(now()), started_(lastSave_) {}

std::vector<std::string> SolveCheckpoint::parse(const std::string& bytes, const std::string& path) const {
    const auto damaged = [&] { return Error(cat(path, ": the checkpoint is damaged; solve again without --resume")); };
    if (bytes.size() < 16 || std::memcmp(bytes.data(), kMagic, 8) != 0)
        throw Error(cat(path, ": not a checkpoint of this version of penumbra; solve again without --resume"));
    size_t at = 8;
    const auto take = [&](uint64_t& v) {
        if (at + sizeof v > bytes.size()) throw damaged();
        std::memcpy(&v, bytes.data() + at, sizeof v);
        at += sizeof v;
    };
    const auto text = [&](std::string& s) {
        uint64_t length = 0;
        take(length);
        if (length > bytes.size() - at) throw damaged();
        s.assign(bytes.data() + at, size_t(length));
        at += size_t(length);
    };
    std::string identity;
    text(identity);
    if (identity != identity_) {
        // Name what differs: the first line that does.
        const std::vector<std::string> theirs = lines(identity), ours = lines(identity_);
        for (size_t k = 0; k < std::max(theirs.size(), ours.size()); ++k) {
            const std::string a = k < theirs.size() ? theirs[k] : "", b = k < ours.size() ? ours[k] : "";
            if (a == b) continue;
            const std::string what = b.substr(0, b.find(':'));
            if (what == "settings") {
                // The first setting that differs, by its report.json key.
                std::istringstream x(a.substr(a.find(':') + 1)), y(b.substr(b.find(':') + 1));
                for (std::string p, q; x >> p && y >> q;)
                    if (p != q)
                        throw Error(cat(path, ": this checkpoint was made with other settings (", p, ", here ", q,
                                        "); resume with the same options, or solve again without --resume"));
            }
            const std::string why = what == "scene"      ? "another scene (or another version of this scene file)"
                                    : what == "settings" ? "other settings"
                                    : what == "build"    ? "another build of penumbra"
                                                         : "another format";
            throw Error(cat(path, ": this checkpoint was made for ", why, " (there '", a, "', here '", b,
                            "'); solve again without --resume"));
        }
    }
    uint64_t passes = 0;
    take(passes);
    if (passes > 1000) throw damaged();
    std::vector<std::string> out(static_cast<size_t>(passes));
    for (std::string& rows : out) text(rows);
    if (at != bytes.size()) throw damaged();
    return out;
}

void SolveCheckpoint::resume(const std::string& bytes) { saved_ = parse(bytes, path_); }

std::string SolveCheckpoint::ownPath() const { return cat(path_, ".rank-", cluster::rank()); }

void SolveCheckpoint::resumeOwn(const std::string& bytes) { own_ = parse(bytes, ownPath()); }

int SolveCheckpoint::beginPass() { return next_++; }

const std::string& SolveCheckpoint::savedRows(int pass) const {
    static const std::string none;
    return pass >= 0 && size_t(pass) < saved_.size() ? saved_[size_t(pass)] : none;
}

bool SolveCheckpoint::due() const {
    return std::getenv("PENUMBRA_TEST_CHECKPOINT_ROWS") || now() - lastSave_ >= kSaveSeconds;
}

namespace {
void appendText(std::string& bytes, std::string_view text) {
    const uint64_t length = text.size();
    bytes.append(reinterpret_cast<const char*>(&length), sizeof length);
    bytes.append(text.data(), text.size());
}
}  // namespace

std::string SolveCheckpoint::fileHead(size_t passes) const {
    std::string bytes(kMagic, 8);
    appendText(bytes, identity_);
    const uint64_t count = passes;
    bytes.append(reinterpret_cast<const char*>(&count), sizeof count);
    return bytes;
}

std::string SolveCheckpoint::shareable() const {
    std::string bytes = fileHead(saved_.size());
    for (const std::string& pass : saved_)
        appendText(bytes, isRowBlockPass(pass) ? std::string_view(kRowBlockTag, sizeof kRowBlockTag) : pass);
    return bytes;
}

namespace {
// Tests: PENUMBRA_TEST_KILL_AT_SAVE=m kills the run by SIGKILL right after its m-th save (with row
// blocks, every rank once all have saved).
void killAtTestSave(int saves, bool everyRank) {
    if (const char* kill = std::getenv("PENUMBRA_TEST_KILL_AT_SAVE"); kill && std::atoi(kill) == saves) {
        if (everyRank) cluster::barrier();
        std::raise(SIGKILL);
    }
}
}  // namespace

void SolveCheckpoint::save(int pass, std::string rows) {
    if (pass < 0) return;
    if (saved_.size() <= size_t(pass)) saved_.resize(size_t(pass) + 1);
    saved_[size_t(pass)] = std::move(rows);
    saved_.resize(size_t(pass) + 1);  // a later pass of an older run no longer follows
    lastSave_ = now();
    if (!cluster::leader() || !writesNow()) return;
    std::string bytes = fileHead(saved_.size());
    for (const std::string& s : saved_) appendText(bytes, s);
    writeFileAtomic(path_, bytes);
    killAtTestSave(++saves_, false);
}

const std::string& SolveCheckpoint::ownRows(int pass) const {
    if (cluster::leader()) return savedRows(pass);
    static const std::string none;
    return pass >= 0 && size_t(pass) < own_.size() ? own_[size_t(pass)] : none;
}

bool SolveCheckpoint::writesNow() const {
    return std::getenv("PENUMBRA_TEST_CHECKPOINT_ROWS") != nullptr || now() - started_ >= kFirstSaveSeconds;
}

void SolveCheckpoint::saveOwn(int pass, const std::string& head, const char* rows, size_t rowBytes) {
    if (pass < 0) return;
    std::vector<std::string>& passes = cluster::leader() ? saved_ : own_;
    passes.resize(size_t(pass) + 1);  // earlier passes kept, a later one of an older run dropped
    passes[size_t(pass)] = std::string();
    lastSave_ = now();
    std::string bytes = fileHead(passes.size());
    for (size_t k = 0; k < size_t(pass); ++k) appendText(bytes, passes[k]);
    const uint64_t length = head.size() + rowBytes;
    bytes.append(reinterpret_cast<const char*>(&length), sizeof length);
    bytes += head;
    writeFileAtomic(cluster::leader() ? path_ : ownPath(), {bytes, std::string_view(rows, rowBytes)});
    killAtTestSave(++saves_, true);
}

void SolveCheckpoint::forget(int pass) {
    for (std::vector<std::string>* passes : {&saved_, &own_})
        if (pass >= 0 && size_t(pass) < passes->size()) (*passes)[size_t(pass)] = std::string();
}

void SolveCheckpoint::remove() {
    if (!(saves_ > 0 || !saved_.empty() || !own_.empty() || next_ > 0)) return;
    if (!cluster::leader()) {
        ::unlink(ownPath().c_str());
        return;
    }
    ::unlink(path_.c_str());
    // And every rank's rows that it can see (a rank that was stopped by another's failure, or one
    // that the last run had and this one has not), as the others' files on a shared file system.
    const std::filesystem::path main(path_);
    const std::string prefix = main.filename().string() + ".rank-";
    std::error_code ec;
    for (const auto& entry : std::filesystem::directory_iterator(main.parent_path(), ec))
        if (entry.path().filename().string().rfind(prefix, 0) == 0) std::filesystem::remove(entry.path(), ec);
}

}  // namespace penumbra
