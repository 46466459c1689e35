#include "NodePairForce.h"
#include "openmm/OpenMMException.h"
#include "openmm/System.h"
#include "openmm/internal/AssertionUtilities.h"
#include "openmm/internal/ContextImpl.h"
#include "openmm/internal/CustomCPPForceImpl.h"
#include "NodePairForceImpl.h"
#include <algorithm>
#include <cmath>

using namespace OpenMM;
using namespace std;

namespace dnarod {

int NodePairForce::addNode(int p0, int p1, int p2) {
    particles.push_back(p0); particles.push_back(p1); particles.push_back(p2);
    return getNumNodes() - 1;
}

void NodePairForce::getNodeParticles(int index, int& p0, int& p1, int& p2) const {
    if (index < 0 || index >= getNumNodes()) throw OpenMMException("NodePairForce: node index out of range");
    p0 = particles[3 * index]; p1 = particles[3 * index + 1]; p2 = particles[3 * index + 2];
}

void NodePairForce::setParameters(double eps, double sigma, double rcWca, double aDh, double kappa, double rcDh,
                                  int nExclude, bool circular) {
    if (!(sigma > 0) || !(kappa > 0) || rcWca < 0 || rcDh < 0 || nExclude < 1)
        throw OpenMMException("NodePairForce: invalid parameters");
    par.eps = eps; par.sigma = sigma; par.rcWca = rcWca; par.aDh = aDh; par.kappa = kappa; par.rcDh = rcDh;
    par.nExclude = nExclude; par.circular = circular;
}

ForceImpl* NodePairForce::createImpl() const { return new NodePairForceImpl(*this); }

void NodePairList::setup(const NodePairForce::Params& p, int nNodes) {
    par = p;
    n = nNodes;
    rc = std::max(p.rcWca, p.rcDh);
    shiftDh = p.rcDh > 0 ? p.aDh * exp(-p.kappa * p.rcDh) / p.rcDh : 0.0;
    skin = std::max(0.5, 0.25 * rc);
    built = false;
}

DNAROD_CLONES void NodePairList::build(const double* c) {
    // Cells of size rc + skin keyed by their integer coordinates, sorted; each node looks in the 27 cells
    // around its own, pairs (i < j) kept in (i, j) order.
    const double cell = rc + skin;
    keys.resize(n);
    double lo[3] = {c[0], c[1], c[2]};
    for (int i = 1; i < n; i++)
        for (int a = 0; a < 3; a++) lo[a] = std::min(lo[a], c[3 * i + a]);
    auto key = [](long long x, long long y, long long z) {
        return ((unsigned long long) x << 42) | ((unsigned long long) y << 21) | (unsigned long long) z;
    };
    vector<long long> ci(3 * n);
    for (int i = 0; i < n; i++) {
        for (int a = 0; a < 3; a++) ci[3 * i + a] = 1 + (long long) ((c[3 * i + a] - lo[a]) / cell);
        if (ci[3 * i] >= (1 << 20) || ci[3 * i + 1] >= (1 << 20) || ci[3 * i + 2] >= (1 << 20))
            throw OpenMMException("NodePairForce: the chain is too extended for the cell list (over 1e6 cells)");
        keys[i] = make_pair(key(ci[3 * i], ci[3 * i + 1], ci[3 * i + 2]), i);
    }
    std::sort(keys.begin(), keys.end());
    pi.clear();
    pj.clear();
    const double r2max = cell * cell;
    vector<int> nb;
    for (int i = 0; i < n; i++) {
        nb.clear();
        for (int dx = -1; dx <= 1; dx++)
            for (int dy = -1; dy <= 1; dy++)
                for (int dz = -1; dz <= 1; dz++) {
                    const unsigned long long k = key(ci[3 * i] + dx, ci[3 * i + 1] + dy, ci[3 * i + 2] + dz);
                    auto it = std::lower_bound(keys.begin(), keys.end(), make_pair(k, -1));
                    for (; it != keys.end() && it->first == k; ++it) {
                        const int j = it->second;
                        if (j <= i) continue;
                        int sep = j - i;
                        if (par.circular && n - sep < sep) sep = n - sep;
                        if (sep <= par.nExclude) continue;
                        double r2 = 0;
                        for (int a = 0; a < 3; a++) {
                            const double d = c[3 * j + a] - c[3 * i + a];
                            r2 += d * d;
                        }
                        if (r2 < r2max) nb.push_back(j);
                    }
                }
        std::sort(nb.begin(), nb.end());
        for (int j : nb) { pi.push_back(i); pj.push_back(j); }
    }
    ref.assign(c, c + 3 * n);
    built = true;
}

DNAROD_CLONES double NodePairList::evaluate(const double* c, double* F, double& ewca, double& edh) {
    ewca = edh = 0.0;
    if (rc <= 0 || n < 2) return 0.0;
    bool rebuild = !built;
    const double lim = 0.25 * skin * skin;
    for (int i = 0; i < n && !rebuild; i++) {
        const double dx = c[3 * i] - ref[3 * i], dy = c[3 * i + 1] - ref[3 * i + 1], dz = c[3 * i + 2] - ref[3 * i + 2];
        if (!(dx * dx + dy * dy + dz * dz < lim)) rebuild = true;  // also on NaN
    }
    if (rebuild) {
        for (int i = 0; i < 3 * n; i++)
            if (!std::isfinite(c[i])) {
                ewca = edh = NAN;
                return NAN;
            }
        build(c);
    }
    const double rc2 = rc * rc, s2 = par.sigma * par.sigma;
    const size_t m = pi.size();
    for (size_t p = 0; p < m; p++) {
        const int i = pi[p], j = pj[p];
        const double rx = c[3 * j] - c[3 * i], ry = c[3 * j + 1] - c[3 * i + 1], rz = c[3 * j + 2] - c[3 * i + 2];
        const double r2 = rx * rx + ry * ry + rz * rz;
        if (r2 >= rc2) continue;
        const double r = sqrt(r2);
        double fr = 0.0;
        if (r < par.rcWca) {
            const double s6 = (s2 / r2) * (s2 / r2) * (s2 / r2);
            ewca += 4.0 * par.eps * (s6 * s6 - s6) + par.eps;
            fr += 24.0 * par.eps * (2.0 * s6 * s6 - s6) / r;
        }
        if (r < par.rcDh) {
            const double ex = par.aDh * exp(-par.kappa * r) / r;
            edh += ex - shiftDh;
            fr += ex * (par.kappa + 1.0 / r);
        }
        const double g = fr / r;
        F[3 * i] -= g * rx; F[3 * i + 1] -= g * ry; F[3 * i + 2] -= g * rz;
        F[3 * j] += g * rx; F[3 * j + 1] += g * ry; F[3 * j + 2] += g * rz;
    }
    return ewca + edh;
}

} // namespace dnarod
