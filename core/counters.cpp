#include "core/counters.h"

#include <atomic>
#include <deque>
#include <mutex>
#include <vector>

#include "core/error.h"

namespace penumbra {
namespace {

constexpr int kMaxCounters = 64;

// One thread's slots, one per counter, on cache lines of their own: only the owning thread writes
// them (a load and a store, no locked instruction); readers sum every thread's.
struct alignas(64) ThreadSlots {
    std::atomic<uint64_t> value[kMaxCounters] = {};
};

struct Registry {
    std::mutex mutex;
    std::vector<const Counter*> counters;
    std::deque<ThreadSlots> threads;  // a deque keeps addresses stable as threads register
};

Registry& registry() {
    static Registry* r = new Registry;  // never destroyed: counters may count during shutdown
    return *r;
}

ThreadSlots& mySlots() {
    thread_local ThreadSlots* mine = [] {
        Registry& r = registry();
        std::lock_guard<std::mutex> lock(r.mutex);
        return &r.threads.emplace_back();
    }();
    return *mine;
}

// Counter `id` summed over every thread's slots; the caller holds the registry's lock.
uint64_t sumLocked(const Registry& r, int id) {
    uint64_t sum = 0;
    for (const ThreadSlots& t : r.threads) sum += t.value[id].load(std::memory_order_relaxed);
    return sum;
}

}  // namespace

Counter::Counter(const char* name, const char* description) : name_(name), description_(description) {
    Registry& r = registry();
    std::lock_guard<std::mutex> lock(r.mutex);
    PENUMBRA_CHECK(r.counters.size() < size_t(kMaxCounters));
    for (const Counter* c : r.counters) PENUMBRA_CHECK(std::string(c->name_) != name);
    id_ = int(r.counters.size());
    r.counters.push_back(this);
}

void Counter::add(uint64_t n) const {
    std::atomic<uint64_t>& v = mySlots().value[id_];
    v.store(v.load(std::memory_order_relaxed) + n, std::memory_order_relaxed);
}

uint64_t Counter::value() const {
    Registry& r = registry();
    std::lock_guard<std::mutex> lock(r.mutex);
    return sumLocked(r, id_);
}

CounterValues counterValues() {
    Registry& r = registry();
    std::lock_guard<std::mutex> lock(r.mutex);
    CounterValues out;
    for (const Counter* c : r.counters) out[c->name()] = sumLocked(r, c->id_);
    return out;
}

void addCounterValues(const CounterValues& values) {
    std::vector<std::pair<const Counter*, uint64_t>> adds;
    {
        Registry& r = registry();
        std::lock_guard<std::mutex> lock(r.mutex);
        for (const Counter* c : r.counters) {
            const auto it = values.find(c->name());
            if (it != values.end() && it->second > 0) adds.emplace_back(c, it->second);
        }
    }
    for (const auto& [counter, n] : adds) counter->add(n);
}

CounterValues countersSince(const CounterValues& before) {
    CounterValues now = counterValues();
    for (auto& [name, value] : now) {
        const auto then = before.find(name);
        if (then != before.end()) value -= then->second;
    }
    return now;
}

std::string counterDescription(const std::string& name) {
    Registry& r = registry();
    std::lock_guard<std::mutex> lock(r.mutex);
    for (const Counter* c : r.counters)
        if (name == c->name()) return c->description();
    return {};
}

}  // namespace penumbra
