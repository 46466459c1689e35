#ifndef DNAROD_WORKERS_H_
#define DNAROD_WORKERS_H_
// A persistent pool of worker threads for the integrator's per-step phases. Written here rather than using
// OpenMM's ThreadPool because that one hands every task over through a mutex and condition variables (a
// sleep and a wake-up per phase, tens of microseconds on a busy machine, several times per step); here the
// threads spin briefly on an atomic generation counter first (a phase of a 10^4-node step takes ~0.1-1 ms,
// so the next one usually arrives while they spin) and only then sleep on a condition variable.
// The caller runs task 0 itself; run() returns when every task has finished.
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>
#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#define DNAROD_PAUSE() _mm_pause()
#else
#define DNAROD_PAUSE() std::this_thread::yield()
#endif

namespace dnarod {

class Workers {
public:
    /** A pool running tasks 0..n-1 (task 0 on the calling thread, n-1 background threads). */
    explicit Workers(int n) : count(n) {
        for (int t = 1; t < n; t++) threads.emplace_back([this, t] { loop(t); });
    }
    ~Workers() {
        {
            std::lock_guard<std::mutex> lk(m);
            stop = true;
            generation.fetch_add(1, std::memory_order_release);
        }
        wake.notify_all();
        for (auto& th : threads) th.join();
    }
    Workers(const Workers&) = delete;
    Workers& operator=(const Workers&) = delete;
    int size() const { return count; }
    /** Run f(t) for t = 0..size()-1 concurrently and wait for all of them. */
    void run(const std::function<void(int)>& f) {
        if (count == 1) {
            f(0);
            return;
        }
        task = &f;
        pending.store(count - 1, std::memory_order_relaxed);
        {
            std::lock_guard<std::mutex> lk(m);
            generation.fetch_add(1, std::memory_order_release);
        }
        wake.notify_all();
        f(0);
        for (int i = 0; i < SPIN && pending.load(std::memory_order_acquire) != 0; i++) DNAROD_PAUSE();
        if (pending.load(std::memory_order_acquire) != 0) {
            std::unique_lock<std::mutex> lk(m);
            done.wait(lk, [this] { return pending.load(std::memory_order_acquire) == 0; });
        }
    }
private:
    static const int SPIN = 4000;  // pause instructions (some 10-100 microseconds) before sleeping
    void loop(int t) {
        uint64_t seen = 0;
        for (;;) {
            uint64_t g = generation.load(std::memory_order_acquire);
            for (int i = 0; i < SPIN && g == seen; i++) {
                DNAROD_PAUSE();
                g = generation.load(std::memory_order_acquire);
            }
            if (g == seen) {
                std::unique_lock<std::mutex> lk(m);
                wake.wait(lk, [&] { return generation.load(std::memory_order_acquire) != seen; });
                g = generation.load(std::memory_order_acquire);
            }
            seen = g;
            if (stop) return;
            (*task)(t);
            if (pending.fetch_sub(1, std::memory_order_acq_rel) == 1) {
                std::lock_guard<std::mutex> lk(m);
                done.notify_one();
            }
        }
    }
    const int count;
    std::vector<std::thread> threads;
    std::atomic<uint64_t> generation{0};
    std::atomic<int> pending{0};
    const std::function<void(int)>* task = nullptr;
    bool stop = false;
    std::mutex m;
    std::condition_variable wake, done;
};

} // namespace dnarod

#endif
