// The processes of one run: this one alone, or the ranks that mpirun started (Open MPI, through its
// C API: transport, launch and membership are its, nothing here is home-made). Launched by mpirun
// (OMPI_COMM_WORLD_SIZE in the environment), start() joins the job; otherwise every call below is
// that of a job of one rank, and MPI is never initialised.
//
// Work is shared by rank, each rank computing its own share with the same seeded streams as one
// process would (rows of an image, chunks of photons), then exchanged so that every rank holds the
// whole: the answer is the same, bit for bit, whatever the number of ranks. Rank 0, the leader, logs
// and writes the outputs; the others say only their errors.
#pragma once

#include <atomic>
#include <cstdint>
#include <cstring>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <type_traits>
#include <vector>

namespace penumbra::cluster {

// Joins the job when mpirun started this process (once, first thing in main); a no-op otherwise.
void start(int* argc, char*** argv);
// Leaves it (at a normal exit); a no-op when not started.
void stop();

int rank();
int size();
inline bool distributed() { return size() > 1; }
inline bool leader() { return rank() == 0; }
// This rank's host name.
const std::string& host();
// "rank 2 on node7": how messages name a rank.
std::string rankName(int r);
// Ranks started on this host (OMPI_COMM_WORLD_LOCAL_SIZE; 1 alone).
int ranksOnHost();

// A failure of one rank that the others cannot know about: "penumbra: " + message goes to stderr
// (the caller names the rank where it matters), and the whole job ends with `code` (MPI_Abort).
// Alone: exit(code).
[[noreturn]] void abortJob(const std::string& message, int code);

// While one lives, this rank works as a job of one (size() 1, rank() 0, the exchanges its own):
// the leader's work that the others do not share (reading a stored solution to send them, a command
// that one rank runs).
class Alone {
public:
    Alone();
    ~Alone();
    Alone(const Alone&) = delete;
    Alone& operator=(const Alone&) = delete;

private:
    bool was_;
};

// Whether this rank computes item k of a list dealt out in turn (k % size == rank).
inline bool owns(int64_t k) { return k % size() == rank(); }

// Items [0, count) handed out as they are asked for, to the threads of every rank (a tile queue: a
// rank on a faster or less busy host takes more). Rank 0 keeps the queue, its own threads taking
// one item at a time; another rank asks it for a run at a time, a quarter of what is left per rank
// (guided self-scheduling: long runs first, single items at the end), and says with each request
// how many items it finished, so that rank 0's one progress bar counts the whole job's. Rank 0's
// threads answer requests as they take their items, and afterwards finish() until every rank has
// been told that none are left. Built and finished by every rank together; alone, a shared counter.
class WorkQueue {
public:
    // `finished(k)`: on rank 0, k more items are done somewhere (the progress bar's update).
    explicit WorkQueue(int64_t count, std::function<void(int64_t)> finished = {});
    ~WorkQueue();
    WorkQueue(const WorkQueue&) = delete;
    WorkQueue& operator=(const WorkQueue&) = delete;

    // The next item for the calling thread (any of this rank's), or -1 when none are left.
    int64_t next();
    // The calling thread has finished an item it took.
    void done();
    // Once this rank's threads have had their -1: rank 0 answers the others until each has had its.
    void finish();
    // The items this rank took, ascending.
    std::vector<int64_t> taken() const;

private:
    // Whether the ranks ask rank 0 for runs (else each takes the items dealt to it in turn).
    static bool asking();
    void serve();  // rank 0: answers the requests waiting
    int64_t count_;
    std::function<void(int64_t)> finished_;
    int tag_;
    std::atomic<int64_t> next_{0};        // rank 0 (or alone): the first item not handed out
    std::atomic<int64_t> doneHere_{0};    // other ranks: finished, not yet reported
    std::mutex mutex_;                    // MPI calls, the run and the items taken
    int64_t runFirst_ = 0, runLeft_ = 0;  // other ranks: the run received, not yet taken
    bool exhausted_ = false;              // other ranks: told that none are left
    int told_ = 0;                        // rank 0: ranks told that none are left
    std::vector<int64_t> taken_;
};

// Calls body(item) for every item of a WorkQueue of `count`, on this rank's threads (each thread
// first calls `prepare`, if given); returns the items this rank did, ascending.
std::vector<int64_t> forEachQueued(int64_t count, const std::function<void(int64_t)>& body,
                                   const std::function<void(int64_t)>& finished = {},
                                   const std::function<void()>& prepare = {});

// The end of work shared among the ranks (each doing its part, as forEachQueued and the other
// sharing does): every rank adds the others' counts since `before` to its counters (core/counters.h),
// so that rank 0's report counts the job's work, as one process's would. Work every rank repeats
// (the iterations) is not shared, and each counts it once, as its own.
void shareCounters(const std::map<std::string, uint64_t>& before);

// Every rank's bytes, in rank order, on every rank.
std::vector<std::string> allGather(const std::string& mine);
// Rank `root`'s bytes on every rank (the others' `bytes` are not read).
std::string broadcast(const std::string& bytes, int root = 0);
// toEach[r] to rank r, from every rank: returns what each rank sent this one, in rank order
// (MPI_Alltoallv). Alone: {toEach[0]}.
std::vector<std::string> exchange(const std::vector<std::string>& toEach);
// Waits for every rank.
void barrier();
// Bytes sent by this rank so far (what the exchanges above handed to MPI).
uint64_t bytesSent();

// Plain data that goes over the wire as its bytes: standard layout, nothing to destroy (Eigen's
// fixed-size vectors count, though they declare their own copies and so are not "trivially copyable").
template <typename T>
constexpr bool kPlainData = std::is_standard_layout_v<T>&& std::is_trivially_destructible_v<T>;

// Items of plain data T, per chunk: each rank filled the chunks it owns (owns(c)); afterwards
// every rank holds every chunk's, as one process would have made them.
template <typename T>
void shareChunks(std::vector<std::vector<T>>& chunks) {
    static_assert(kPlainData<T>);
    if (!distributed()) return;
    std::string mine;
    for (size_t c = 0; c < chunks.size(); ++c) {
        if (!owns(int64_t(c))) continue;
        const uint64_t n = chunks[c].size();
        mine.append(reinterpret_cast<const char*>(&n), sizeof n);
        mine.append(reinterpret_cast<const char*>(chunks[c].data()), n * sizeof(T));
    }
    const std::vector<std::string> all = allGather(mine);
    for (int r = 0; r < size(); ++r) {
        if (r == rank()) continue;
        size_t at = 0;
        for (size_t c = size_t(r); c < chunks.size(); c += size_t(size())) {
            uint64_t n = 0;
            std::memcpy(&n, all[size_t(r)].data() + at, sizeof n);
            at += sizeof n;
            chunks[c].resize(n);
            std::memcpy(static_cast<void*>(chunks[c].data()), all[size_t(r)].data() + at, n * sizeof(T));
            at += n * sizeof(T);
        }
    }
}

// Values and vectors of plain data into bytes, for the exchanges above, and back in the same order.
class Packer {
public:
    template <typename T>
    void put(const T& v) {
        static_assert(kPlainData<T>);
        bytes.append(reinterpret_cast<const char*>(&v), sizeof(T));
    }
    template <typename T>
    void put(const std::vector<T>& v) {
        put(v.data(), v.size());
    }
    // `count` items at `data`, as a vector of them (without making one).
    template <typename T>
    void put(const T* data, size_t count) {
        static_assert(kPlainData<T>);
        put(uint64_t(count));
        bytes.append(reinterpret_cast<const char*>(data), count * sizeof(T));
    }
    std::string bytes;
};

class Unpacker {
public:
    explicit Unpacker(const std::string& bytes) : bytes_(bytes) {}
    template <typename T>
    void get(T& v) {
        static_assert(kPlainData<T>);
        take(&v, sizeof(T));
    }
    template <typename T>
    void get(std::vector<T>& v) {
        static_assert(kPlainData<T>);
        uint64_t n = 0;
        get(n);
        v.resize(n);
        take(v.data(), n * sizeof(T));
    }
    // A vector of exactly `count` items into `to`; false (nothing read) when it holds another count.
    template <typename T>
    bool get(T* to, size_t count) {
        static_assert(kPlainData<T>);
        const size_t at = at_;
        uint64_t n = 0;
        get(n);
        if (n != count) return at_ = at, false;
        take(to, n * sizeof(T));
        return true;
    }
    bool done() const { return at_ == bytes_.size(); }

private:
    void take(void* to, size_t count);
    const std::string& bytes_;
    size_t at_ = 0;
};

// One plain-data value per chunk, shared as shareChunks does.
template <typename T>
void shareValues(std::vector<T>& values) {
    if (!distributed()) return;
    std::vector<std::vector<T>> chunks(values.size());
    for (size_t c = 0; c < values.size(); ++c)
        if (owns(int64_t(c))) chunks[c] = {values[c]};
    shareChunks(chunks);
    for (size_t c = 0; c < values.size(); ++c) values[c] = chunks[c].at(0);
}

}  // namespace penumbra::cluster
