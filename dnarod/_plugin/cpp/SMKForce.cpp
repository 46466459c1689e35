#include "SMKForce.h"
#include "SMKForceImpl.h"
#include "openmm/OpenMMException.h"
#include "openmm/internal/ContextImpl.h"
#include "openmm/internal/CustomCPPForceImpl.h"
#include "openmm/internal/AssertionUtilities.h"
#include <cmath>
#include <limits>

using namespace OpenMM;
using namespace std;

#ifndef DNAROD_OPENMM_VERSION
#define DNAROD_OPENMM_VERSION "unknown"
#endif

namespace dnarod {

const char* builtAgainstOpenMM() { return DNAROD_OPENMM_VERSION; }

// Cayley-limit denominator 1 + tr R > 2 (1 + cos(theta_max)), theta_max = pi - 1e-4 the largest admissible step
// rotation (dnarod.rotations.MAX_CAYLEY_ANGLE, as in dnarod.kernels).
static const double denLimit = 2.0 * (1.0 + cos(M_PI - 1e-4));

SMKForce::SMKForce() : ds(0.34), closureQ({1, 0, 0, 0, 1, 0, 0, 0, 1}), closureT({0, 0, 0}) {}

int SMKForce::addNode(int p0, int p1, int p2, double radius) {
    if (!(radius > 0)) throw OpenMMException("SMKForce: node radius must be positive");
    Node nd;
    nd.p[0] = p0; nd.p[1] = p1; nd.p[2] = p2; nd.radius = radius;
    nodes.push_back(nd);
    return (int) nodes.size() - 1;
}

static void copyParams(SMKForce::Step& s, const vector<double>& K, const vector<double>& xi0) {
    if (K.size() != 36 || xi0.size() != 6)
        throw OpenMMException("SMKForce: a step needs 36 stiffness values and 6 intrinsic strains");
    for (int i = 0; i < 36; i++) s.K[i] = K[i];
    for (int i = 0; i < 6; i++) s.xi0[i] = xi0[i];
}

int SMKForce::addStep(int left, int right, const vector<double>& K, const vector<double>& xi0, bool image) {
    Step s;
    s.left = left; s.right = right; s.image = image;
    copyParams(s, K, xi0);
    steps.push_back(s);
    return (int) steps.size() - 1;
}

void SMKForce::setStepParameters(int index, const vector<double>& K, const vector<double>& xi0) {
    ASSERT_VALID_INDEX(index, steps);
    copyParams(steps[index], K, xi0);
}

void SMKForce::getStepParameters(int index, int& left, int& right, vector<double>& K, vector<double>& xi0,
                                 bool& image) const {
    ASSERT_VALID_INDEX(index, steps);
    const Step& s = steps[index];
    left = s.left; right = s.right; image = s.image;
    K.assign(s.K, s.K + 36);
    xi0.assign(s.xi0, s.xi0 + 6);
}

void SMKForce::getNode(int index, int& p0, int& p1, int& p2, double& radius) const {
    ASSERT_VALID_INDEX(index, nodes);
    p0 = nodes[index].p[0]; p1 = nodes[index].p[1]; p2 = nodes[index].p[2]; radius = nodes[index].radius;
}

void SMKForce::setClosure(const vector<double>& Q, const vector<double>& t) {
    if (Q.size() != 9 || t.size() != 3) throw OpenMMException("SMKForce: closure needs Q (9 values) and t (3)");
    closureQ = Q;
    closureT = t;
}

// ---------------------------------------------------------------------------------------------------------
// Node poses and loads
// ---------------------------------------------------------------------------------------------------------
void nodePoses(const vector<SMKForce::Node>& nodes, const vector<Vec3>& pos, double* c, double* L) {
    const double s3 = sqrt(3.0);
    const size_t n = nodes.size();
    for (size_t k = 0; k < n; k++) {
        const Vec3& a0 = pos[nodes[k].p[0]];
        const Vec3& a1 = pos[nodes[k].p[1]];
        const Vec3& a2 = pos[nodes[k].p[2]];
        const double u = 1.0 / (3.0 * nodes[k].radius), v = 1.0 / (s3 * nodes[k].radius);
        double* ck = c + 3 * k;
        double* Lk = L + 9 * k;
        for (int r = 0; r < 3; r++) {
            ck[r] = (a0[r] + a1[r] + a2[r]) / 3.0;
            Lk[3 * r + 0] = (2.0 * a0[r] - a1[r] - a2[r]) * u;
            Lk[3 * r + 1] = (a1[r] - a2[r]) * v;
        }
        Lk[2] = Lk[3 * 1 + 0] * Lk[3 * 2 + 1] - Lk[3 * 2 + 0] * Lk[3 * 1 + 1];
        Lk[5] = Lk[3 * 2 + 0] * Lk[3 * 0 + 1] - Lk[3 * 0 + 0] * Lk[3 * 2 + 1];
        Lk[8] = Lk[3 * 0 + 0] * Lk[3 * 1 + 1] - Lk[3 * 1 + 0] * Lk[3 * 0 + 1];
    }
}

// Loads of one step (a port of dnarod.core.kernels.step_loads, docs/formulation.md §4): left node a (pose ca, La), right node b
// (pose cb, Lb, already mapped through the closure if it is an image). Adds the left loads to Fa, ta, and
// returns the right loads (lab, before the closure map) in Fb, tb. Returns the step energy or NaN.
static inline __attribute__((always_inline)) double stepLoads(const SMKForce::Step& s, double ds, double inv, const double* ca, const double* La,
                               const double* cb, const double* Lb, double* Fa, double* ta, double* Fb, double* tb) {
    double R[9];
    for (int a = 0; a < 3; a++)
        for (int b = 0; b < 3; b++)
            R[3 * a + b] = La[a] * Lb[b] + La[3 + a] * Lb[3 + b] + La[6 + a] * Lb[6 + b];
    const double den = 1.0 + R[0] + R[4] + R[8];
    if (!(den > denLimit)) return numeric_limits<double>::quiet_NaN();
    const double iden = 2.0 / den;
    const double w0 = (R[7] - R[5]) * iden, w1 = (R[2] - R[6]) * iden, w2 = (R[3] - R[1]) * iden;
    const double e0 = cb[0] - ca[0], e1 = cb[1] - ca[1], e2 = cb[2] - ca[2];
    double d[6];
    d[0] = w0 * inv - s.xi0[0];
    d[1] = w1 * inv - s.xi0[1];
    d[2] = w2 * inv - s.xi0[2];
    d[3] = (La[0] * e0 + La[3] * e1 + La[6] * e2) * inv - s.xi0[3];
    d[4] = (La[1] * e0 + La[4] * e1 + La[7] * e2) * inv - s.xi0[4];
    d[5] = (La[2] * e0 + La[5] * e1 + La[8] * e2) * inv - s.xi0[5];
    double sig[6];
    for (int i = 0; i < 6; i++) {
        const double* Ki = s.K + 6 * i;
        sig[i] = Ki[0] * d[0] + Ki[1] * d[1] + Ki[2] * d[2] + Ki[3] * d[3] + Ki[4] * d[4] + Ki[5] * d[5];
    }
    const double H = d[0] * sig[0] + d[1] * sig[1] + d[2] * sig[2] + d[3] * sig[3] + d[4] * sig[4] + d[5] * sig[5];
    const double M0 = sig[0], M1 = sig[1], M2 = sig[2], P0 = sig[3], P1 = sig[4], P2 = sig[5];
    const double wM = w0 * M0 + w1 * M1 + w2 * M2;
    const double bm0 = M0 + 0.5 * (w1 * M2 - w2 * M1) + 0.25 * w0 * wM;
    const double bm1 = M1 + 0.5 * (w2 * M0 - w0 * M2) + 0.25 * w1 * wM;
    const double bm2 = M2 + 0.5 * (w0 * M1 - w1 * M0) + 0.25 * w2 * wM;
    const double n0 = La[0] * P0 + La[1] * P1 + La[2] * P2;
    const double n1 = La[3] * P0 + La[4] * P1 + La[5] * P2;
    const double n2 = La[6] * P0 + La[7] * P1 + La[8] * P2;
    const double m0 = La[0] * bm0 + La[1] * bm1 + La[2] * bm2;
    const double m1 = La[3] * bm0 + La[4] * bm1 + La[5] * bm2;
    const double m2 = La[6] * bm0 + La[7] * bm1 + La[8] * bm2;
    Fa[0] += n0; Fa[1] += n1; Fa[2] += n2;
    ta[0] += m0 + e1 * n2 - e2 * n1;
    ta[1] += m1 + e2 * n0 - e0 * n2;
    ta[2] += m2 + e0 * n1 - e1 * n0;
    Fb[0] = -n0; Fb[1] = -n1; Fb[2] = -n2;
    tb[0] = -m0; tb[1] = -m1; tb[2] = -m2;
    return 0.5 * ds * H;
}

DNAROD_CLONES double chainLoadsRange(const vector<SMKForce::Step>& steps, int begin, int end, double ds,
                                     const double* Q, const double* t, const double* c, const double* L, double* F,
                                     double* tau, double* carryF, double* carryT, int& badStep) {
    double E = 0.0;
    badStep = -1;
    double Fb[3], tb[3], cimg[3], Limg[9];
    const double invDs = 1.0 / ds;  // (the compiler does not hoist this division out of the loop itself)
    if (carryF != nullptr)
        for (int a = 0; a < 3; a++) carryF[a] = carryT[a] = 0.0;
    for (int k = begin; k < end; k++) {
        const SMKForce::Step& s = steps[k];
        const double* cb = c + 3 * s.right;
        const double* Lb = L + 9 * s.right;
        if (s.image) {
            for (int r = 0; r < 3; r++) {
                cimg[r] = t[r] + Q[3 * r] * cb[0] + Q[3 * r + 1] * cb[1] + Q[3 * r + 2] * cb[2];
                for (int col = 0; col < 3; col++)
                    Limg[3 * r + col] = Q[3 * r] * Lb[col] + Q[3 * r + 1] * Lb[3 + col] + Q[3 * r + 2] * Lb[6 + col];
            }
            cb = cimg;
            Lb = Limg;
        }
        const double e = stepLoads(s, ds, invDs, c + 3 * s.left, L + 9 * s.left, cb, Lb, F + 3 * s.left, tau + 3 * s.left,
                                   Fb, tb);
        if (e != e) {
            if (badStep < 0) badStep = k;
            E = numeric_limits<double>::quiet_NaN();
            continue;
        }
        E += e;
        // The right loads of the range's last step go to the carry (its node may belong to another range).
        const bool carry = carryF != nullptr && k == end - 1;
        double* Fr = carry ? carryF : F + 3 * s.right;
        double* tr = carry ? carryT : tau + 3 * s.right;
        if (s.image) {  // loads on the image act on the node through Q^T
            for (int a = 0; a < 3; a++) {
                Fr[a] += Q[a] * Fb[0] + Q[3 + a] * Fb[1] + Q[6 + a] * Fb[2];
                tr[a] += Q[a] * tb[0] + Q[3 + a] * tb[1] + Q[6 + a] * tb[2];
            }
        } else {
            for (int a = 0; a < 3; a++) { Fr[a] += Fb[a]; tr[a] += tb[a]; }
        }
    }
    return E;
}

double chainLoads(const vector<SMKForce::Step>& steps, double ds, const double* Q, const double* t,
                  const double* c, const double* L, double* F, double* tau, int& badStep) {
    return chainLoadsRange(steps, 0, (int) steps.size(), ds, Q, t, c, L, F, tau, nullptr, nullptr, badStep);
}

ForceImpl* SMKForce::createImpl() const { return new SMKForceImpl(*this); }

bool SMKForce::usesDeviceKernel(Context& context) {
    return dynamic_cast<SMKForceImpl&>(getImplInContext(context)).usesDeviceKernel();
}

void SMKForce::updateParametersInContext(Context& context) {
    dynamic_cast<SMKForceImpl&>(getImplInContext(context)).updateParametersInContext(getContextImpl(context));
}

} // namespace dnarod
