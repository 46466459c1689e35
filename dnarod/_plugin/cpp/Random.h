#ifndef DNAROD_RANDOM_H_
#define DNAROD_RANDOM_H_
// Gaussian random numbers for the thermostat: xoshiro256++ (Blackman & Vigna 2019, public-domain reference
// algorithm) and the ziggurat method of Marsaglia & Tsang (2000, J. Stat. Softw. 5(8), 128 layers), written
// here because the thermostat draws six normals per node per step and std::normal_distribution (polar method,
// a log and a sqrt per pair) cost more than the rest of the step. The 256-bit state is all there is to
// checkpoint (bit-for-bit resume).
#include <cmath>
#include <cstdint>
#include <istream>
#include <ostream>

namespace dnarod {

class Gaussian {
public:
    Gaussian() {
        seed(1);
        const Tables& tb = tables();  // shared by every generator (computed once)
        kn = tb.kn; wn = tb.wn; fn = tb.fn;
    }
    void seed(uint64_t s) {
        for (int i = 0; i < 4; i++) {  // splitmix64
            s += 0x9E3779B97F4A7C15ULL;
            uint64_t z = s;
            z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
            z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
            st[i] = z ^ (z >> 31);
        }
    }
    inline uint64_t next() {
        const uint64_t r = rotl(st[0] + st[3], 23) + st[0];
        const uint64_t t = st[1] << 17;
        st[2] ^= st[0]; st[3] ^= st[1]; st[1] ^= st[2]; st[0] ^= st[3];
        st[2] ^= t;
        st[3] = rotl(st[3], 45);
        return r;
    }
    /** Uniform on (0, 1]. */
    inline double uniform() { return ((next() >> 11) + 1) * (1.0 / 9007199254740992.0); }
    /** Standard normal. */
    inline double operator()() {
        const uint64_t u = next();
        const int iz = (int) (u & 127);
        const int64_t hz = (int32_t) (u >> 32);
        if ((hz < 0 ? -hz : hz) < kn[iz]) return hz * wn[iz];
        return tail(hz, iz);
    }
    /** out[0..count-1] = the next count standard normals (the same numbers as count calls of operator(); the
     *  generator state is held in registers through the loop). */
    inline void fill(double* out, int count) {
        uint64_t s0 = st[0], s1 = st[1], s2 = st[2], s3 = st[3];
        for (int i = 0; i < count; i++) {
            const uint64_t u = rotl(s0 + s3, 23) + s0;
            const uint64_t t = s1 << 17;
            s2 ^= s0; s3 ^= s1; s1 ^= s2; s0 ^= s3;
            s2 ^= t;
            s3 = rotl(s3, 45);
            const int iz = (int) (u & 127);
            const int64_t hz = (int32_t) (u >> 32);
            if ((hz < 0 ? -hz : hz) < kn[iz]) {
                out[i] = hz * wn[iz];
                continue;
            }
            st[0] = s0; st[1] = s1; st[2] = s2; st[3] = s3;
            out[i] = tail(hz, iz);
            s0 = st[0]; s1 = st[1]; s2 = st[2]; s3 = st[3];
        }
        st[0] = s0; st[1] = s1; st[2] = s2; st[3] = s3;
    }
    void save(std::ostream& s) const { s << st[0] << ' ' << st[1] << ' ' << st[2] << ' ' << st[3] << ' '; }
    void load(std::istream& s) {
        s >> st[0] >> st[1] >> st[2] >> st[3];
        s.get();  // the separator written by save()
    }
private:
    static inline uint64_t rotl(uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }
    double tail(int64_t hz, int iz) {
        const double r = 3.442619855899;
        for (;;) {
            const double x = hz * wn[iz];
            if (iz == 0) {
                double xx, y;
                do {
                    xx = -std::log(uniform()) / r;
                    y = -std::log(uniform());
                } while (y + y < xx * xx);
                return hz > 0 ? r + xx : -r - xx;
            }
            if (fn[iz] + uniform() * (fn[iz - 1] - fn[iz]) < std::exp(-0.5 * x * x)) return x;
            const uint64_t u = next();
            iz = (int) (u & 127);
            hz = (int32_t) (u >> 32);
            if ((hz < 0 ? -hz : hz) < kn[iz]) return hz * wn[iz];
        }
    }
    struct Tables {
        int64_t kn[128];
        double wn[128], fn[128];
        Tables() {
            const double m1 = 2147483648.0;
            double dn = 3.442619855899, tn = dn;
            const double vn = 9.91256303526217e-3;
            const double q = vn / std::exp(-0.5 * dn * dn);
            kn[0] = (int64_t) ((dn / q) * m1);
            kn[1] = 0;
            wn[0] = q / m1;
            wn[127] = dn / m1;
            fn[0] = 1.0;
            fn[127] = std::exp(-0.5 * dn * dn);
            for (int i = 126; i >= 1; i--) {
                dn = std::sqrt(-2.0 * std::log(vn / dn + std::exp(-0.5 * dn * dn)));
                kn[i + 1] = (int64_t) ((dn / tn) * m1);
                tn = dn;
                fn[i] = std::exp(-0.5 * dn * dn);
                wn[i] = dn / m1;
            }
        }
    };
    static const Tables& tables() {
        static const Tables t;
        return t;
    }
    uint64_t st[4];
    const int64_t* kn;
    const double* wn;
    const double* fn;
};

} // namespace dnarod

#endif
