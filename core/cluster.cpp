#include "core/cluster.h"

#include <mpi.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <thread>

#include "core/counters.h"
#include "core/error.h"
#include "core/parallel.h"

namespace penumbra::cluster {
namespace {

bool g_started = false;    // MPI initialised (mpirun started this process)
bool g_alone = false;      // an Alone lives: this rank works by itself
bool g_joined = false;     // start() is done
bool g_anyThread = false;  // any thread may call MPI, one at a time (MPI_THREAD_SERIALIZED)
int g_queues = 0;          // work queues made so far: each one's messages have tags of their own
int g_rank = 0, g_size = 1;
uint64_t g_sent = 0;
std::vector<std::string> g_hosts;  // per rank (started), else this host alone

std::string thisHost() {
    char name[256] = {};
    if (gethostname(name, sizeof name - 1) != 0) return "unknown host";
    return name;
}

// An MPI call's failure: the job cannot go on, and the others are stopped with it.
void check(int status, const char* what) {
    if (status == MPI_SUCCESS) return;
    char text[MPI_MAX_ERROR_STRING] = {};
    int length = 0;
    MPI_Error_string(status, text, &length);
    abortJob(cat("error: ", what, " failed on ", rankName(g_rank), ": ", text), 1);
}

int envInt(const char* name, int otherwise) {
    const char* v = std::getenv(name);
    return v && *v ? std::atoi(v) : otherwise;
}

// The most bytes one MPI call moves (its counts are ints): 1 GiB; tests make it small
// (PENUMBRA_TEST_EXCHANGE_BYTES) so that every exchange goes in many rounds.
long long roundBytes() { return std::max(1, envInt("PENUMBRA_TEST_EXCHANGE_BYTES", 1 << 30)); }

}  // namespace

void start(int* argc, char*** argv) {
    if (g_started || !std::getenv("OMPI_COMM_WORLD_SIZE")) return;
    int provided = 0;
    // The exchanges are the main thread's; a work queue's requests and answers come from whichever
    // thread takes the next item, one at a time under the queue's lock.
    if (MPI_Init_thread(argc, argv, MPI_THREAD_SERIALIZED, &provided) != MPI_SUCCESS) {
        std::fprintf(stderr, "penumbra: error: mpirun started this process, but it could not join the job\n");
        std::exit(1);
    }
    g_started = true;
    g_anyThread = provided >= MPI_THREAD_SERIALIZED;
    MPI_Comm_set_errhandler(MPI_COMM_WORLD, MPI_ERRORS_RETURN);
    MPI_Comm_rank(MPI_COMM_WORLD, &g_rank);
    MPI_Comm_size(MPI_COMM_WORLD, &g_size);
    g_hosts = allGather(thisHost());
    g_sent = 0;
    g_joined = true;
}

void stop() {
    if (!g_started) return;
    MPI_Finalize();
    g_started = false;
}

int rank() { return g_alone ? 0 : g_rank; }
int size() { return g_alone ? 1 : g_size; }

Alone::Alone() : was_(g_alone) { g_alone = true; }
Alone::~Alone() { g_alone = was_; }

const std::string& host() {
    if (g_hosts.empty()) g_hosts = {thisHost()};
    return g_hosts.at(size_t(g_rank));
}
std::string rankName(int r) {
    return cat("rank ", r, " on ", r == g_rank ? host() : size_t(r) < g_hosts.size() ? g_hosts[size_t(r)] : "?");
}
int ranksOnHost() { return g_started ? std::max(1, envInt("OMPI_COMM_WORLD_LOCAL_SIZE", 1)) : 1; }

void abortJob(const std::string& message, int code) {
    std::fprintf(stderr, "penumbra: %s\n", message.c_str());
    std::fflush(stderr);
    if (g_started) MPI_Abort(MPI_COMM_WORLD, code);
    std::exit(code);
}

std::vector<std::string> allGather(const std::string& mine) {
    if (!g_started || g_alone) return {mine};
    barrier();  // the early ranks wait asleep for the last one
    const int n = g_size;
    long long length = static_cast<long long>(mine.size());
    std::vector<long long> lengths(static_cast<size_t>(n), 0);
    check(MPI_Allgather(&length, 1, MPI_LONG_LONG, lengths.data(), 1, MPI_LONG_LONG, MPI_COMM_WORLD),
          "exchanging sizes (MPI_Allgather)");
    // Counts and offsets are ints in MPI's C API: each round gathers at most 1 GiB from all ranks
    // together, 1 GiB / ranks from each.
    const long long kStep = std::max(1LL, roundBytes() / n);
    std::vector<std::string> all(static_cast<size_t>(n));
    for (int r = 0; r < n; ++r) all[size_t(r)].resize(size_t(lengths[size_t(r)]));
    for (long long done = 0;; done += kStep) {
        std::vector<int> counts(static_cast<size_t>(n)), offsets(static_cast<size_t>(n));
        long long total = 0;
        for (int r = 0; r < n; ++r) {
            counts[size_t(r)] = int(std::max(0LL, std::min(kStep, lengths[size_t(r)] - done)));
            offsets[size_t(r)] = int(total);
            total += counts[size_t(r)];
        }
        if (total == 0) break;
        std::string buffer(size_t(total), '\0');
        const int sent = counts[size_t(g_rank)];
        check(MPI_Allgatherv(mine.data() + std::min<long long>(done, length), sent, MPI_BYTE, buffer.data(),
                             counts.data(), offsets.data(), MPI_BYTE, MPI_COMM_WORLD),
              "exchanging results (MPI_Allgatherv)");
        g_sent += uint64_t(sent);
        for (int r = 0; r < n; ++r)
            std::memcpy(all[size_t(r)].data() + done, buffer.data() + offsets[size_t(r)], size_t(counts[size_t(r)]));
    }
    return all;
}

std::string broadcast(const std::string& bytes, int root) {
    if (!g_started || g_alone) return bytes;
    barrier();
    long long length = static_cast<long long>(bytes.size());
    check(MPI_Bcast(&length, 1, MPI_LONG_LONG, root, MPI_COMM_WORLD), "broadcasting a size (MPI_Bcast)");
    std::string out = g_rank == root ? bytes : std::string(size_t(length), '\0');
    const long long kStep = roundBytes();
    for (long long done = 0; done < length; done += kStep) {
        const int count = int(std::min(kStep, length - done));
        check(MPI_Bcast(out.data() + done, count, MPI_BYTE, root, MPI_COMM_WORLD), "broadcasting (MPI_Bcast)");
        if (g_rank == root) g_sent += uint64_t(count);
    }
    return out;
}

std::vector<std::string> exchange(const std::vector<std::string>& toEach) {
    if (!g_started || g_alone) return {toEach.at(0)};
    PENUMBRA_CHECK(toEach.size() == size_t(g_size));
    barrier();
    const int n = g_size;
    std::vector<long long> sending(static_cast<size_t>(n)), receiving(static_cast<size_t>(n));
    for (int r = 0; r < n; ++r) sending[size_t(r)] = static_cast<long long>(toEach[size_t(r)].size());
    check(MPI_Alltoall(sending.data(), 1, MPI_LONG_LONG, receiving.data(), 1, MPI_LONG_LONG, MPI_COMM_WORLD),
          "exchanging sizes (MPI_Alltoall)");
    std::vector<std::string> from(static_cast<size_t>(n));
    for (int r = 0; r < n; ++r) from[size_t(r)].resize(size_t(receiving[size_t(r)]));
    // In steps of at most roundBytes() / ranks to and from each rank (MPI's counts are ints), as many
    // as the longest message anywhere needs: every rank takes part in every step.
    const long long kStep = std::max(1LL, roundBytes() / n);
    long long longest = 0, longestAnywhere = 0;
    for (int r = 0; r < n; ++r) longest = std::max({longest, sending[size_t(r)], receiving[size_t(r)]});
    check(MPI_Allreduce(&longest, &longestAnywhere, 1, MPI_LONG_LONG, MPI_MAX, MPI_COMM_WORLD),
          "exchanging sizes (MPI_Allreduce)");
    for (long long done = 0; done < longestAnywhere; done += kStep) {
        std::vector<int> sendCounts(static_cast<size_t>(n)), sendOffsets(static_cast<size_t>(n)),
            receiveCounts(static_cast<size_t>(n)), receiveOffsets(static_cast<size_t>(n));
        long long sent = 0, received = 0;
        for (int r = 0; r < n; ++r) {
            const size_t k = size_t(r);
            sendCounts[k] = int(std::max(0LL, std::min(kStep, sending[k] - done)));
            receiveCounts[k] = int(std::max(0LL, std::min(kStep, receiving[k] - done)));
            sendOffsets[k] = int(sent), receiveOffsets[k] = int(received);
            sent += sendCounts[k], received += receiveCounts[k];
        }
        std::string out(size_t(sent), '\0'), in(size_t(received), '\0');
        for (int r = 0; r < n; ++r)
            std::memcpy(out.data() + sendOffsets[size_t(r)],
                        toEach[size_t(r)].data() + std::min(done, sending[size_t(r)]), size_t(sendCounts[size_t(r)]));
        check(MPI_Alltoallv(out.data(), sendCounts.data(), sendOffsets.data(), MPI_BYTE, in.data(),
                            receiveCounts.data(), receiveOffsets.data(), MPI_BYTE, MPI_COMM_WORLD),
              "exchanging rows (MPI_Alltoallv)");
        g_sent += uint64_t(sent - sendCounts[size_t(g_rank)]);
        for (int r = 0; r < n; ++r)
            std::memcpy(from[size_t(r)].data() + done, in.data() + receiveOffsets[size_t(r)],
                        size_t(receiveCounts[size_t(r)]));
    }
    return from;
}

void barrier() {
    if (!g_started || g_alone) return;
    // Tests: PENUMBRA_TEST_KILL_RANK=r makes rank r die by SIGKILL at its first exchange, as a
    // crashed process or a lost host would (tests/test_cluster.cpp).
    if (g_joined && envInt("PENUMBRA_TEST_KILL_RANK", -1) == g_rank) std::raise(SIGKILL);
    // Polled with short sleeps: a blocking MPI_Barrier spins, and a rank that waits (for the leader's
    // solve, for the slowest rank's rows) would take a core from the ranks still working.
    MPI_Request request;
    check(MPI_Ibarrier(MPI_COMM_WORLD, &request), "waiting for the other ranks (MPI_Ibarrier)");
    for (int done = 0;;) {
        check(MPI_Test(&request, &done, MPI_STATUS_IGNORE), "waiting for the other ranks (MPI_Test)");
        if (done) return;
        std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
}

uint64_t bytesSent() { return g_sent; }

namespace {
// Waits for a request to complete, asleep between tests: a rank waiting for an answer leaves the
// core to the threads still working.
void await(MPI_Request& request, const char* what) {
    for (int spins = 0;; ++spins) {
        int done = 0;
        check(MPI_Test(&request, &done, MPI_STATUS_IGNORE), what);
        if (done) return;
        if (spins < 64)
            std::this_thread::yield();
        else
            std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
}
}  // namespace

// Without MPI_THREAD_SERIALIZED (an MPI built without it) or alone, nothing is asked of anyone: each
// rank takes the items dealt to it in turn (owns), from a shared counter over them.
bool WorkQueue::asking() {
    // PENUMBRA_DEAL_IN_TURN=1: items dealt in turn, as before the queue (to measure the two).
    static const bool inTurn = envInt("PENUMBRA_DEAL_IN_TURN", 0) == 1;
    return distributed() && g_anyThread && !inTurn;
}

WorkQueue::WorkQueue(int64_t count, std::function<void(int64_t)> finished)
    : count_(count), finished_(std::move(finished)), tag_(2 * (g_queues++ % 16000) + 1) {}

WorkQueue::~WorkQueue() = default;

int64_t WorkQueue::next() {
    // Tests: PENUMBRA_TEST_SLOW_RANK=r makes rank r take 20 ms more per item, as a slower or busier
    // host would (tests/test_cluster.cpp).
    static const int slow = envInt("PENUMBRA_TEST_SLOW_RANK", -1);
    if (slow == g_rank && distributed()) std::this_thread::sleep_for(std::chrono::milliseconds(20));
    if (!asking()) {
        // Items r, r + size, ...: the k-th of this rank's is item rank + k size.
        const int64_t k = next_.fetch_add(1), item = rank() + k * size();
        if (item >= count_) return -1;
        std::lock_guard<std::mutex> lock(mutex_);
        taken_.push_back(item);
        return item;
    }
    std::lock_guard<std::mutex> lock(mutex_);
    if (leader()) {
        serve();
        const int64_t item = next_.fetch_add(1);
        if (item >= count_) return -1;
        taken_.push_back(item);
        return item;
    }
    if (runLeft_ == 0 && !exhausted_) {
        int64_t report = doneHere_.exchange(0), run[2] = {0, 0};
        MPI_Request request;
        check(MPI_Irecv(run, 2, MPI_INT64_T, 0, tag_ + 1, MPI_COMM_WORLD, &request), "asking for work (MPI_Irecv)");
        check(MPI_Send(&report, 1, MPI_INT64_T, 0, tag_, MPI_COMM_WORLD), "asking for work (MPI_Send)");
        g_sent += sizeof report;
        await(request, "asking for work (MPI_Test)");
        runFirst_ = run[0], runLeft_ = run[1];
        exhausted_ = runLeft_ == 0;
    }
    if (runLeft_ == 0) return -1;
    --runLeft_;
    taken_.push_back(runFirst_++);
    return taken_.back();
}

void WorkQueue::serve() {
    for (;;) {
        int waiting = 0;
        MPI_Status status;
        check(MPI_Iprobe(MPI_ANY_SOURCE, tag_, MPI_COMM_WORLD, &waiting, &status), "handing out work (MPI_Iprobe)");
        if (!waiting) return;
        int64_t report = 0;
        check(MPI_Recv(&report, 1, MPI_INT64_T, status.MPI_SOURCE, tag_, MPI_COMM_WORLD, MPI_STATUS_IGNORE),
              "handing out work (MPI_Recv)");
        if (finished_ && report > 0) finished_(report);
        const int64_t left = std::max<int64_t>(0, count_ - next_.load());
        const int64_t want = std::max<int64_t>(1, left / (4 * int64_t(size())));
        const int64_t first = next_.fetch_add(want);
        int64_t run[2] = {first, std::clamp<int64_t>(count_ - first, 0, want)};
        told_ += run[1] == 0;
        check(MPI_Send(run, 2, MPI_INT64_T, status.MPI_SOURCE, tag_ + 1, MPI_COMM_WORLD),
              "handing out work (MPI_Send)");
        g_sent += sizeof run;
    }
}

void WorkQueue::done() {
    if (leader()) {
        if (finished_) finished_(1);
    } else {
        ++doneHere_;
    }
}

void WorkQueue::finish() {
    if (!asking() || !leader()) return;
    for (;;) {
        {
            std::lock_guard<std::mutex> lock(mutex_);
            serve();
            if (told_ == size() - 1) return;
        }
        std::this_thread::sleep_for(std::chrono::microseconds(500));
    }
}

std::vector<int64_t> WorkQueue::taken() const {
    std::vector<int64_t> items = taken_;
    std::sort(items.begin(), items.end());
    return items;
}

std::vector<int64_t> forEachQueued(int64_t count, const std::function<void(int64_t)>& body,
                                   const std::function<void(int64_t)>& finished, const std::function<void()>& prepare) {
    const CounterValues before = counterValues();
    WorkQueue queue(count, finished);
    // One loop per thread, each taking items until none are left.
    parallelFor(threadCount(), [&](int64_t t0, int64_t t1) {
        if (prepare) prepare();
        for (int64_t t = t0; t < t1; ++t)
            for (int64_t item; (item = queue.next()) >= 0;) {
                body(item);
                queue.done();
            }
    });
    queue.finish();
    shareCounters(before);
    return queue.taken();
}

void shareCounters(const CounterValues& before) {
    if (!distributed()) return;
    Packer packed;
    for (const auto& [name, value] : countersSince(before)) {
        packed.put(std::vector<char>(name.begin(), name.end()));
        packed.put(uint64_t(value));
    }
    const std::vector<std::string> all = allGather(packed.bytes);
    for (int r = 0; r < size(); ++r) {
        if (r == rank()) continue;
        CounterValues theirs;
        Unpacker in(all[size_t(r)]);
        while (!in.done()) {
            std::vector<char> name;
            uint64_t value = 0;
            in.get(name);
            in.get(value);
            theirs[std::string(name.begin(), name.end())] = value;
        }
        addCounterValues(theirs);
    }
}

void Unpacker::take(void* to, size_t count) {
    // Another rank of the same program packed these bytes: a short read is this program's fault.
    PENUMBRA_CHECK(at_ + count <= bytes_.size());
    if (count) std::memcpy(to, bytes_.data() + at_, count);
    at_ += count;
}

}  // namespace penumbra::cluster
