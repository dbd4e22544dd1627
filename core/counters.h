// Named counters (pbrt's STAT_COUNTER): each is defined once, at file scope beside the work it counts,
//   Counter g_rays("rays.occlusion", "occlusion rays traced");
// incremented from any thread without waiting for another (each thread owns its slots), and read in
// one place: counterValues() for report.json, the bench and the log. A run reports what it did as
// the difference of two readings (countersSince), so a process may run many.
#pragma once

#include <cstdint>
#include <map>
#include <string>

namespace penumbra {

class Counter;
using CounterValues = std::map<std::string, uint64_t>;

class Counter {
public:
    // `name` is dotted, stage first ("form_factors.kernel_evaluations"); both strings must outlive the
    // process (literals). Counters are static objects: registering at start-up, never destroyed.
    Counter(const char* name, const char* description);
    Counter(const Counter&) = delete;
    Counter& operator=(const Counter&) = delete;

    void add(uint64_t n = 1) const;
    uint64_t value() const;  // summed over threads
    const char* name() const { return name_; }
    const char* description() const { return description_; }

private:
    friend CounterValues counterValues();
    const char* name_;
    const char* description_;
    int id_;
};

// Every registered counter's value now, by name.
CounterValues counterValues();
// What changed since `before`: every counter, its value now minus then.
CounterValues countersSince(const CounterValues& before);
// Adds `values` to the counters of those names (the work other ranks did, cluster.h), from this thread.
void addCounterValues(const CounterValues& values);
// The description registered with `name` (empty if none).
std::string counterDescription(const std::string& name);

}  // namespace penumbra
