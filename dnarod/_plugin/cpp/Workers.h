#ifndef DNAROD_WORKERS_H_
#define DNAROD_WORKERS_H_
// A persistent pool of worker threads for the integrator's per-step phases. Written here rather than using
// OpenMM's ThreadPool because that one hands every task over through a mutex and condition variables and waits
// for every thread: a sleep and a wake-up per phase (tens of microseconds, and a whole scheduler time slice when
// the machine is busy), several times per step. Here a phase is a list of chunks that the calling thread and the
// workers claim from one atomic counter: the caller starts at once and does every chunk itself if no worker comes
// (a worker that is asleep or not scheduled costs nothing but a wake-up call); a worker spins briefly on the
// counter before it sleeps, so one that is running joins within a microsecond. Which thread runs a chunk does not
// matter to the result (each chunk has its own data), so results do not depend on the number of threads.
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
    /** The calling thread plus n - 1 background threads. */
    explicit Workers(int n) : count(n) {
        for (int t = 1; t < n; t++) threads.emplace_back([this] { loop(); });
    }
    ~Workers() {
        {
            std::lock_guard<std::mutex> lk(m);
            stop = true;
            claim.store(((claim.load() >> 32) + 1) << 32, std::memory_order_release);
        }
        wake.notify_all();
        for (auto& th : threads) th.join();
    }
    Workers(const Workers&) = delete;
    Workers& operator=(const Workers&) = delete;
    int size() const { return count; }
    /** Run f(c) for c = 0..chunks-1, each exactly once, on the calling thread and any worker that joins; returns
     *  when all have finished. */
    void run(int chunks, const std::function<void(int)>& f) {
        if (count == 1 || chunks == 1) {
            for (int c = 0; c < chunks; c++) f(c);
            return;
        }
        task.store(&f, std::memory_order_relaxed);
        total.store(chunks, std::memory_order_relaxed);
        finished.store(0, std::memory_order_relaxed);
        const uint64_t gen = (claim.load(std::memory_order_relaxed) >> 32) + 1;
        {
            std::lock_guard<std::mutex> lk(m);
            claim.store(gen << 32, std::memory_order_release);
        }
        wake.notify_all();
        work(gen);
        for (int i = 0; i < SPIN && finished.load(std::memory_order_acquire) != chunks; i++) DNAROD_PAUSE();
        if (finished.load(std::memory_order_acquire) != chunks) {
            std::unique_lock<std::mutex> lk(m);
            done.wait(lk, [&] { return finished.load(std::memory_order_acquire) == chunks; });
        }
    }
private:
    static const int SPIN = 4000;  // pause instructions (some 10-100 microseconds) before sleeping
    // Claim and run chunks of generation gen until none is left (or the generation has moved on).
    void work(uint64_t gen) {
        uint64_t v = claim.load(std::memory_order_acquire);
        for (;;) {
            if ((v >> 32) != gen) return;
            const int c = (int) (v & 0xffffffffu);
            // read before the claim; if the generation moved on meanwhile, the claim fails
            const std::function<void(int)>* f = task.load(std::memory_order_relaxed);
            const int n = total.load(std::memory_order_relaxed);
            if (c >= n) return;
            if (!claim.compare_exchange_weak(v, v + 1, std::memory_order_acq_rel, std::memory_order_acquire))
                continue;
            (*f)(c);
            if (finished.fetch_add(1, std::memory_order_acq_rel) + 1 == n) {
                std::lock_guard<std::mutex> lk(m);
                done.notify_all();
            }
            v = claim.load(std::memory_order_acquire);
        }
    }
    void loop() {
        uint64_t seen = 0;
        for (;;) {
            uint64_t g = claim.load(std::memory_order_acquire) >> 32;
            for (int i = 0; i < SPIN && g == seen; i++) {
                DNAROD_PAUSE();
                g = claim.load(std::memory_order_acquire) >> 32;
            }
            if (g == seen) {
                std::unique_lock<std::mutex> lk(m);
                wake.wait(lk, [&] { return (claim.load(std::memory_order_acquire) >> 32) != seen || stop; });
                g = claim.load(std::memory_order_acquire) >> 32;
            }
            seen = g;
            if (stop) return;
            work(g);
        }
    }
    const int count;
    std::vector<std::thread> threads;
    std::atomic<uint64_t> claim{0};  // generation (high 32 bits) and next chunk (low 32 bits)
    std::atomic<int> finished{0};
    std::atomic<const std::function<void(int)>*> task{nullptr};
    std::atomic<int> total{0};
    bool stop = false;
    std::mutex m;
    std::condition_variable wake, done;
};

} // namespace dnarod

#endif
