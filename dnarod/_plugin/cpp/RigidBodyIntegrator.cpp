#include "RigidBodyIntegrator.h"
#include "SMKForceImpl.h"
#include "RigidBodyKernels.h"
#include "NodePairForceImpl.h"
#include "Workers.h"
#include "openmm/Context.h"
#include "openmm/OpenMMException.h"
#include "openmm/System.h"
#include "openmm/internal/ContextImpl.h"
#include "openmm/reference/ReferencePlatform.h"
#include "openmm/kernels.h"
#include "openmm/VerletIntegrator.h"
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <istream>
#include <ostream>

using namespace OpenMM;
using namespace std;

namespace dnarod {

// Boltzmann constant in kJ/mol/K (the value of dnarod.units / OpenMM's BOLTZ).
static const double KB = 0.0083144626181532;
static const double S3 = 1.7320508075688772;
// Unit offsets of the three particles in body coordinates (dnarod.openmm.particles.BODY_OFFSETS).
static const double OFF[3][2] = {{1.0, 0.0}, {-0.5, 0.8660254037844386}, {-0.5, -0.8660254037844386}};

// Seed of chunk t's Gaussian stream (stream 0: the seed itself, as with one chunk).
static uint64_t streamSeed(uint64_t base, int t) {
    return t == 0 ? base : base ^ (0xD1B54A32D192ED03ULL * (uint64_t) t);
}

RigidBodyIntegrator::RigidBodyIntegrator(double stepSize, double temperature, double friction)
    : temperature(temperature), friction(friction), seed(0) {
    setStepSize(stepSize);
    setTemperature(temperature);
    setFriction(friction);
    setConstraintTolerance(1e-8);
}

RigidBodyIntegrator::~RigidBodyIntegrator() {}

void RigidBodyIntegrator::setNodesPerChunk(int m) {
    if (context != nullptr) throw OpenMMException("RigidBodyIntegrator: set the nodes per chunk before creating the Context");
    if (m < 1) throw OpenMMException("RigidBodyIntegrator: nodes per chunk must be >= 1");
    chunkNodes = (m + BLOCK - 1) / BLOCK * BLOCK;
}

void RigidBodyIntegrator::setTemperature(double t) {
    if (!(t >= 0)) throw OpenMMException("RigidBodyIntegrator: temperature must be >= 0 K");
    temperature = t;
}

void RigidBodyIntegrator::setFriction(double f) {
    if (!(f >= 0)) throw OpenMMException("RigidBodyIntegrator: friction must be >= 0 1/ps");
    friction = f;
}

int RigidBodyIntegrator::addNode(int p0, int p1, int p2, double radius) {
    if (context != nullptr) throw OpenMMException("RigidBodyIntegrator: add nodes before creating the Context");
    if (!(radius > 0)) throw OpenMMException("RigidBodyIntegrator: node radius must be positive");
    nodeP.push_back(p0); nodeP.push_back(p1); nodeP.push_back(p2);
    nodeR.push_back(radius);
    return getNumNodes() - 1;
}

vector<string> RigidBodyIntegrator::getKernelNames() {
    return {IntegrateVerletStepKernel::Name()};
}

// Called by OpenMM when the Context is destroyed or re-created (Context.reinitialize): forget everything bound to
// the old ContextImpl, so that initialize() can bind the new one (a preserved state comes back through
// loadCheckpoint, which restores the node state kept here).
void RigidBodyIntegrator::cleanup() {
    context = nullptr;
    refData = nullptr;
    fused = nullptr;
    pairs = nullptr;
    otherGroups = 0;
    haveOther = false;
    cacheValid = false;
    loadsValid = false;
    setupKernel = Kernel();
    placeholder.reset();
    workers.reset();
    numThreads = 1;
}

void RigidBodyIntegrator::initialize(ContextImpl& ctx) {
    if (context != nullptr && context != &ctx)
        throw OpenMMException("RigidBodyIntegrator: this integrator is already bound to a Context");
    context = &ctx;
    const System& system = ctx.getSystem();
    const int n = getNumNodes();
    vector<int> owner(system.getNumParticles(), -1);
    mass.assign(n, 0.0);
    for (int k = 0; k < n; k++) {
        double m[3];
        for (int i = 0; i < 3; i++) {
            int p = nodeP[3 * k + i];
            if (p < 0 || p >= system.getNumParticles())
                throw OpenMMException("RigidBodyIntegrator: a node refers to a particle that is not in the System");
            if (owner[p] >= 0) throw OpenMMException("RigidBodyIntegrator: a particle belongs to two nodes");
            owner[p] = k;
            m[i] = system.getParticleMass(p);
        }
        if (m[0] != m[1] || m[0] != m[2])
            throw OpenMMException("RigidBodyIntegrator: the three particles of a node must have equal masses");
        mass[k] = 3.0 * m[0];
    }
    for (int p = 0; p < system.getNumParticles(); p++)
        if (owner[p] < 0 && system.getParticleMass(p) != 0.0)
            throw OpenMMException("RigidBodyIntegrator: every particle with mass must belong to a node");
    for (int i = 0; i < system.getNumParticles(); i++)
        if (system.isVirtualSite(i)) throw OpenMMException("RigidBodyIntegrator: virtual sites are not supported");
    // Fuse the SMK and node-pair forces if they are integrated here and their nodes are ours; every other force
    // (and a fused one sharing a force group with it) is evaluated by OpenMM.
    fused = nullptr;
    pairs = nullptr;
    otherGroups = 0;
    const int groups = getIntegrationForceGroups();
    for (ForceImpl* impl : ctx.getForceImpls()) {
        const int g = impl->getOwner().getForceGroup();
        if (!(groups & (1 << g))) continue;
        SMKForceImpl* smk = dynamic_cast<SMKForceImpl*>(impl);
        if (smk != nullptr && fused == nullptr) {
            const SMKForce& f = smk->getOwner();
            bool same = f.getNumNodes() == n;
            for (int k = 0; same && k < n; k++) {
                int a, b, d;
                double r;
                f.getNode(k, a, b, d, r);
                same = a == nodeP[3 * k] && b == nodeP[3 * k + 1] && d == nodeP[3 * k + 2] && r == nodeR[k];
            }
            if (same) {
                fused = smk;
                continue;
            }
        }
        NodePairForceImpl* np = dynamic_cast<NodePairForceImpl*>(impl);
        if (np != nullptr && pairs == nullptr) {
            const NodePairForce& f = np->getOwner();
            if (f.particleList() == nodeP) {
                pairs = np;
                continue;
            }
        }
        otherGroups |= 1 << g;
    }
    // A force OpenMM evaluates shares a group with a fused one: OpenMM would count the fused one again, so
    // un-fuse it (then its group is evaluated by OpenMM too) until nothing changes.
    for (;;) {
        otherGroups = 0;
        for (ForceImpl* impl : ctx.getForceImpls()) {
            const int g = impl->getOwner().getForceGroup();
            if ((groups & (1 << g)) && impl != (ForceImpl*) fused && impl != (ForceImpl*) pairs) otherGroups |= 1 << g;
        }
        bool changed = false;
        if (fused != nullptr && (otherGroups & (1 << fused->getOwner().getForceGroup()))) fused = nullptr, changed = true;
        if (pairs != nullptr && (otherGroups & (1 << pairs->getOwner().getForceGroup()))) pairs = nullptr, changed = true;
        if (!changed) break;
    }
    haveOther = otherGroups != 0;
    const string name = ctx.getPlatform().getName();
    refData = (name == "Reference" || name == "CPU") ? ctx.getPlatformData() : nullptr;
    if (refData == nullptr) {
        // GPU platforms (OpenCL, CUDA) set up their device arrays when an integration kernel is initialised;
        // this integrator works through ContextImpl's host copies, so it initialises (and never runs) a Verlet
        // kernel for that.
        placeholder.reset(new VerletIntegrator(getStepSize()));
        setupKernel = ctx.getPlatform().createKernel(IntegrateVerletStepKernel::Name(), ctx);
        setupKernel.getAs<IntegrateVerletStepKernel>().initialize(system, *(VerletIntegrator*) placeholder.get());
    }
    c.resize(3 * n);
    L.resize(9 * n);
    cP.assign(3 * n, 0.0);
    cPi.assign(3 * n, 0.0);
    cacheValid = false;
    loadsValid = false;
    F.resize(3 * n);
    tau.resize(3 * n);
    // Chunks of chunkNodes nodes (whole blocks), each with the SMK steps starting in it and its own Gaussian
    // stream; threads: the CPU platform's Threads property (what dnarod's --threads sets), at most one per chunk.
    int threads = 1;
    if (name == "CPU") {
        try {
            threads = std::max(1, std::atoi(ctx.getPlatform().getPropertyValue(ctx.getOwner(), "Threads").c_str()));
        } catch (const std::exception&) {
            threads = 1;
        }
    }
    numChunks = std::max(1, (n + chunkNodes - 1) / chunkNodes);
    chunkStart.assign(numChunks + 1, n);
    for (int ch = 0; ch < numChunks; ch++) chunkStart[ch] = ch * chunkNodes;
    numThreads = std::max(1, std::min(threads, numChunks));
    chainRanges = fused != nullptr && fused->isChain() && fused->numSteps() >= n - 1;
    workers.reset(numThreads > 1 ? new Workers(numThreads) : nullptr);
    carry.assign(6 * numChunks, 0.0);
    partE.assign(numChunks, 0.0);
    baseSeed = seed != 0 ? (uint64_t) seed : ((uint64_t) std::random_device()() << 32) ^ std::random_device()();
    normals.resize(numChunks);
    for (int ch = 0; ch < numChunks; ch++) normals[ch].seed(streamSeed(baseSeed, ch));
    invMass.assign(n, 0.0);
    invJ12.assign(n, 0.0);
    for (int k = 0; k < n; k++)
        if (mass[k] > 0) {
            invMass[k] = 1.0 / mass[k];
            invJ12[k] = 2.0 / (mass[k] * nodeR[k] * nodeR[k]);
        }
    sigP.resize(n);
    sigPi.resize(3 * n);
    for (int k = 0; k < n; k++) {
        const double l2 = nodeR[k] * nodeR[k];
        sigP[k] = sqrt(mass[k]);
        sigPi[3 * k] = sigPi[3 * k + 1] = sqrt(0.5 * mass[k] * l2);
        sigPi[3 * k + 2] = sqrt(mass[k] * l2);
    }
    // On a device platform with dnarod's kernel library the whole step runs there, every force through OpenMM.
    onDevice = refData == nullptr && ctx.getPlatform().supportsKernels({IntegrateRigidBodyStepKernel::Name()});
    if (onDevice) {
        fused = nullptr;
        pairs = nullptr;
        otherGroups = groups;
        haveOther = true;
        deviceKernel = ctx.getPlatform().createKernel(IntegrateRigidBodyStepKernel::Name(), ctx);
        static_cast<IntegrateRigidBodyStepKernel&>(deviceKernel.getImpl()).initialize(system, nodeP, nodeR, mass, seed);
    }
}

// SMK steps of chunk ch: those starting in its node range (the last chunk also takes the closure step).
void RigidBodyIntegrator::chunkSteps(int ch, int& begin, int& end) const {
    begin = chunkStart[ch];
    end = ch == numChunks - 1 ? fused->numSteps() : chunkStart[ch + 1];
}

// SMK loads of chunk ch's steps (the right loads of its last step go to its carry).
void RigidBodyIntegrator::loadsRange(int ch) {
    const int k0 = chunkStart[ch], k1 = chunkStart[ch + 1];
    std::fill(F.begin() + 3 * k0, F.begin() + 3 * k1, 0.0);
    std::fill(tau.begin() + 3 * k0, tau.begin() + 3 * k1, 0.0);
    int begin, end, bad;
    chunkSteps(ch, begin, end);
    partE[ch] = fused->nodeLoadsRange(begin, end, c.data(), L.data(), F.data(), tau.data(), &carry[6 * ch],
                                      &carry[6 * ch + 3], bad);
}

// Node loads (lab force F, torque tau about the centre) at the current positions, c and L already set.
void RigidBodyIntegrator::loads(bool needOther) {
    lastE[0] = lastE[1] = lastE[2] = 0.0;
    if (fused != nullptr && chainRanges) {
        // Chunks of the chain (on any threads); the loads a chunk puts on the first node of the next (or, for the
        // closure, on node 0) are added afterwards. Every node gets the same two SMK terms as in one pass over
        // the chain and 0 + a + b = 0 + b + a, so the loads are bitwise those of one pass.
        parallel([this](int ch) { loadsRange(ch); });
        for (int ch = 0; ch < numChunks; ch++) {
            int begin, end, left, right;
            chunkSteps(ch, begin, end);
            if (end <= begin) continue;
            fused->stepNodes(end - 1, left, right);
            for (int a = 0; a < 3; a++) {
                F[3 * right + a] += carry[6 * ch + a];
                tau[3 * right + a] += carry[6 * ch + 3 + a];
            }
            lastE[0] += partE[ch];
        }
    } else {
        std::fill(F.begin(), F.end(), 0.0);
        std::fill(tau.begin(), tau.end(), 0.0);
        if (fused != nullptr) {
            int bad;
            lastE[0] = fused->nodeLoads(c.data(), L.data(), F.data(), tau.data(), bad);
        }
    }
    if (pairs != nullptr) {
        pairs->nodeForces(c.data(), F.data());
        lastE[1] = pairs->lastWca;
        lastE[2] = pairs->lastDh;
    }
    if (!needOther) return;
    context->calcForcesAndEnergy(true, false, otherGroups);
    otherLoads(c.data(), refData != nullptr ? ((ReferencePlatform::PlatformData*) refData)->positions : &posBuf,
               F.data(), tau.data());
}

// Adds the forces OpenMM computed last (for otherGroups) to node forces FF and torques tt about centres cc.
void RigidBodyIntegrator::otherLoads(const double* cc, const vector<Vec3>* p, double* FF, double* tt) {
    const vector<Vec3>* f;
    if (refData != nullptr) {
        f = ((ReferencePlatform::PlatformData*) refData)->forces;
    } else {
        context->getForces(forceBuf);
        f = &forceBuf;
    }
    const int n = getNumNodes();
    for (int k = 0; k < n; k++) {
        double* Fk = &FF[3 * k];
        double* tk = &tt[3 * k];
        for (int i = 0; i < 3; i++) {
            const Vec3& fi = (*f)[nodeP[3 * k + i]];
            const Vec3& pi = (*p)[nodeP[3 * k + i]];
            const double x0 = pi[0] - cc[3 * k], x1 = pi[1] - cc[3 * k + 1], x2 = pi[2] - cc[3 * k + 2];
            Fk[0] += fi[0]; Fk[1] += fi[1]; Fk[2] += fi[2];
            tk[0] += x1 * fi[2] - x2 * fi[1];
            tk[1] += x2 * fi[0] - x0 * fi[2];
            tk[2] += x0 * fi[1] - x1 * fi[0];
        }
    }
}

// sin and cos: Taylor polynomials for |x| < 0.8 (truncation < 1e-19, as dnarod.integrators.fast._sincos; rotor
// angles per sub-step are ~0.05 rad at the default step), libm beyond.
static inline __attribute__((always_inline)) void sinCosPoly(double x, double& s, double& c) {
    const double x2 = x * x;
    s = x * (1.0 + x2 * (-1.0 / 6 + x2 * (1.0 / 120 + x2 * (-1.0 / 5040 + x2 * (1.0 / 362880 + x2 * (
            -1.0 / 39916800 + x2 * (1.0 / 6227020800 + x2 * (-1.0 / 1307674368000 + x2 * (
            1.0 / 355687428096000)))))))));
    c = 1.0 + x2 * (-0.5 + x2 * (1.0 / 24 + x2 * (-1.0 / 720 + x2 * (1.0 / 40320 + x2 * (
            -1.0 / 3628800 + x2 * (1.0 / 479001600 + x2 * (-1.0 / 87178291200 + x2 * (
            1.0 / 20922789888000 + x2 * (-1.0 / 6402373705728000)))))))));
}

static inline void sinCos(double x, double& s, double& c) {
    if (std::fabs(x) < 0.8) {
        sinCosPoly(x, s, c);
        return;
    }
    s = std::sin(x);
    c = std::cos(x);
}

// Exact free-rotor sub-flow of every lane by angle scale * pi_a / J_a about body axis a: rotates frame columns
// b, d and body momenta pi_b, pi_d. POLY: all angles are below 0.8 rad (then the polynomial sin/cos); a template
// parameter, so each variant's lane loop is compiled (and vectorised) without a branch inside it.
template <bool POLY>
static inline __attribute__((always_inline)) void subBlockT(RigidBodyIntegrator::Block& B, int a, int b, int d, double scale) {
    for (int j = 0; j < RigidBodyIntegrator::BLOCK; j++) {
        const double x = scale * B.pi[a][j] * B.iJ[a][j];
        double s, co;
        if (POLY)
            sinCosPoly(x, s, co);
        else
            sinCos(x, s, co);
        for (int r = 0; r < 3; r++) {
            const double xb = B.L[3 * r + b][j], xd = B.L[3 * r + d][j];
            B.L[3 * r + b][j] = co * xb + s * xd;
            B.L[3 * r + d][j] = co * xd - s * xb;
        }
        const double qb = B.pi[b][j], qd = B.pi[d][j];
        B.pi[b][j] = co * qb + s * qd;
        B.pi[d][j] = co * qd - s * qb;
    }
}

static inline __attribute__((always_inline)) void subBlock(RigidBodyIntegrator::Block& B, int a, int b, int d, double scale, bool poly) {
    if (poly)
        subBlockT<true>(B, a, b, d, scale);
    else
        subBlockT<false>(B, a, b, d, scale);
}

// Free rotor for time h: R1(h/2) R2(h/2) R3(h) R2(h/2) R1(h/2) (dnarod.integrators.splitting.rotor_flow).
static inline __attribute__((always_inline)) void rotorBlock(RigidBodyIntegrator::Block& B, double h, bool poly) {
    const double hh = 0.5 * h;
    subBlock(B, 0, 1, 2, hh, poly);
    subBlock(B, 1, 2, 0, hh, poly);
    subBlock(B, 2, 0, 1, h, poly);
    subBlock(B, 1, 2, 0, hh, poly);
    subBlock(B, 0, 1, 2, hh, poly);
}

void RigidBodyIntegrator::step(int steps) {
    if (onDevice) {
        static_cast<IntegrateRigidBodyStepKernel&>(deviceKernel.getImpl()).execute(
            *context, steps, getStepSize(), temperature, friction, getIntegrationForceGroups());
        return;
    }
    run(steps);
}

DNAROD_CLONES void RigidBodyIntegrator::run(int steps) {
    if (context == nullptr) throw OpenMMException("RigidBodyIntegrator: not bound to a Context");
    const double dt = getStepSize();
    const double cfric = exp(-friction * dt);
    const double kT = KB * temperature;
    const double noise = sqrt(std::max(0.0, 1.0 - cfric * cfric) * kT);
    vector<Vec3>* pos;
    vector<Vec3>* vel;
    for (int s = 0; s < steps; s++) {
        const bool other = haveOther;
        if (other) context->updateContextState();
        if (refData != nullptr) {
            pos = ((ReferencePlatform::PlatformData*) refData)->positions;
            vel = ((ReferencePlatform::PlatformData*) refData)->velocities;
        } else {
            context->getPositions(posBuf);
            context->getVelocities(velBuf);
            pos = &posBuf;
            vel = &velBuf;
        }
        // With only fused forces on the Reference/CPU platforms the node state of the last step is kept (c, L,
        // cP, cPi; checkpointed, dropped by stateChanged when the Context's positions or velocities are set) and
        // particles are written once per call; otherwise it is read back from the particles every step.
        if (s == 0 && cacheValid && verifyParticles) {
            cacheValid = particlesMatch(pos, vel);
            verifyParticles = false;
        }
        const bool useCache = cacheValid && !other && refData != nullptr;
        const bool write = other || refData == nullptr || (s == steps - 1 && !deferWrite);
        if (!useCache) {
            parallel([&](int ch) { nodePoses(chunkStart[ch], chunkStart[ch + 1], pos, c.data(), L.data()); });
        }
        // The loads at the kept node state were computed already if a report asked for them (same inputs, same
        // result: skipping them changes nothing).
        const long long version = fused != nullptr ? fused->version : 0;
        if (!(s == 0 && useCache && loadsValid && loadsVersion == version)) loads(other);
        loadsValid = false;
        stepDt = dt;
        stepCfric = cfric;
        stepNoise = noise;
        parallel([&](int ch) { update(ch, pos, vel, useCache, write); });
        if (refData == nullptr) {
            context->setPositions(posBuf);
            context->setVelocities(velBuf);
        }
        cacheValid = !other && refData != nullptr;
        context->setTime(context->getTime() + dt);
        context->setStepCount(context->getStepCount() + 1);
    }
}

// The node update of chunk t's nodes: kick, drift, rotor (and thermostat, from the chunk's own stream), and
// with write the rigid particles.
DNAROD_CLONES void RigidBodyIntegrator::update(int t, vector<Vec3>* pos, vector<Vec3>* vel, bool useCache, bool write) {
    const int n = getNumNodes();
    const double dt = stepDt, cfric = stepCfric, noise = stepNoise;
    const bool langevin = friction > 0;
    Gaussian& normal = normals[t];
    // Nodes in blocks of BLOCK lanes: the rotor's sub-flows are long dependent chains per node, so each
    // sub-flow runs over all lanes of a block at once (independent work the compiler vectorises).
    Block B;
    for (int b0 = chunkStart[t]; b0 < chunkStart[t + 1]; b0 += BLOCK) {
        const int nb = std::min(BLOCK, n - b0);
        double bound = 0.0;
        for (int j = 0; j < BLOCK; j++) {
            const int k = b0 + j;
            if (j >= nb || mass[k] == 0.0) {  // padding lane or clamped node: nothing moves
                for (int a = 0; a < 9; a++) B.L[a][j] = a % 4 == 0 ? 1.0 : 0.0;
                for (int a = 0; a < 3; a++) B.c[a][j] = B.P[a][j] = B.pi[a][j] = B.iJ[a][j] = B.sPi[a][j] = 0.0;
                B.im[j] = B.sP[j] = 0.0;
                continue;
            }
            const double* ck = &c[3 * k];
            const double* Lk = &L[9 * k];
            const double m = mass[k];
            const double* Fk = &F[3 * k];
            const double* tk = &tau[3 * k];
            double p2 = 0.0;
            if (useCache) {
                for (int a = 0; a < 3; a++) {
                    B.P[a][j] = cP[3 * k + a] + dt * Fk[a];
                    B.pi[a][j] = cPi[3 * k + a] + dt * (Lk[a] * tk[0] + Lk[3 + a] * tk[1] + Lk[6 + a] * tk[2]);
                    B.c[a][j] = ck[a];
                    p2 += B.pi[a][j] * B.pi[a][j];
                }
            } else {
            // Node velocity and body angular momentum from the particle velocities.
            double v[3] = {0, 0, 0}, h[3] = {0, 0, 0};
            for (int i = 0; i < 3; i++) {
                const Vec3& u = (*vel)[nodeP[3 * k + i]];
                v[0] += u[0] / 3.0; v[1] += u[1] / 3.0; v[2] += u[2] / 3.0;
            }
            for (int i = 0; i < 3; i++) {
                const Vec3& u = (*vel)[nodeP[3 * k + i]];
                const Vec3& p = (*pos)[nodeP[3 * k + i]];
                const double x0 = p[0] - ck[0], x1 = p[1] - ck[1], x2 = p[2] - ck[2];
                const double u0 = u[0] - v[0], u1 = u[1] - v[1], u2 = u[2] - v[2];
                h[0] += x1 * u2 - x2 * u1;
                h[1] += x2 * u0 - x0 * u2;
                h[2] += x0 * u1 - x1 * u0;
            }
            // sum_i x_i x du_i = l^2 L diag(3/2, 3/2, 3) L^T omega_lab, so pi = J omega_body = m/3 L^T sum(..).
            // V: kick by dt (lab momentum by F, body angular momentum by L^T tau).
            for (int a = 0; a < 3; a++) {
                B.P[a][j] = m * v[a] + dt * Fk[a];
                B.pi[a][j] = (m / 3.0) * (Lk[a] * h[0] + Lk[3 + a] * h[1] + Lk[6 + a] * h[2])
                             + dt * (Lk[a] * tk[0] + Lk[3 + a] * tk[1] + Lk[6 + a] * tk[2]);
                B.c[a][j] = ck[a];
                p2 += B.pi[a][j] * B.pi[a][j];
            }
            }
            for (int a = 0; a < 9; a++) B.L[a][j] = Lk[a];
            B.im[j] = invMass[k];
            B.iJ[0][j] = B.iJ[1][j] = invJ12[k];
            B.iJ[2][j] = 0.5 * invJ12[k];
            B.sP[j] = noise * sigP[k];
            for (int a = 0; a < 3; a++) B.sPi[a][j] = noise * sigPi[3 * k + a];
            // |pi| is invariant under the rotor, so this bounds every sub-flow angle of the step.
            bound = std::max(bound, p2 * invJ12[k] * invJ12[k]);
        }
        const double hmax = langevin ? 0.5 * dt : dt;
        const bool poly = bound * hmax * hmax < 0.64;
        if (!langevin) {
            for (int a = 0; a < 3; a++)
                for (int j = 0; j < BLOCK; j++) B.c[a][j] += dt * B.P[a][j] * B.im[j];
            rotorBlock(B, dt, poly);
        } else {
            const double hdt = 0.5 * dt;
            for (int a = 0; a < 3; a++)
                for (int j = 0; j < BLOCK; j++) B.c[a][j] += hdt * B.P[a][j] * B.im[j];
            rotorBlock(B, hdt, poly);
            // Normals in the order P[0][0], pi[0][0], P[0][1], ... (one stream per chunk).
            double z[6 * BLOCK];
            normal.fill(z, 6 * nb);
            for (int a = 0; a < 3; a++)
                for (int j = 0; j < nb; j++) {
                    B.P[a][j] = cfric * B.P[a][j] + B.sP[j] * z[2 * (a * nb + j)];
                    B.pi[a][j] = cfric * B.pi[a][j] + B.sPi[a][j] * z[2 * (a * nb + j) + 1];
                }
            for (int a = 0; a < 3; a++)
                for (int j = 0; j < BLOCK; j++) B.c[a][j] += hdt * B.P[a][j] * B.im[j];
            rotorBlock(B, hdt, poly);
        }
        // Keep the node state; write the rigid triangles: p_i = c + l L b_i, u_i = v + (L omega) x (p_i - c).
        for (int j = 0; j < nb; j++) {
            const int k = b0 + j;
            if (mass[k] == 0.0) continue;
            for (int a = 0; a < 3; a++) {
                c[3 * k + a] = B.c[a][j];
                cP[3 * k + a] = B.P[a][j];
                cPi[3 * k + a] = B.pi[a][j];
            }
            for (int a = 0; a < 9; a++) L[9 * k + a] = B.L[a][j];
            if (!write) continue;
            const double l = nodeR[k];
            double w[3];
            for (int a = 0; a < 3; a++) w[a] = B.pi[a][j] * B.iJ[a][j];
            double Lk[9];
            for (int a = 0; a < 9; a++) Lk[a] = B.L[a][j];
            const double wl0 = Lk[0] * w[0] + Lk[1] * w[1] + Lk[2] * w[2];
            const double wl1 = Lk[3] * w[0] + Lk[4] * w[1] + Lk[5] * w[2];
            const double wl2 = Lk[6] * w[0] + Lk[7] * w[1] + Lk[8] * w[2];
            const double v0 = B.P[0][j] * B.im[j], v1 = B.P[1][j] * B.im[j], v2 = B.P[2][j] * B.im[j];
            for (int i = 0; i < 3; i++) {
                const double x0 = l * (Lk[0] * OFF[i][0] + Lk[1] * OFF[i][1]);
                const double x1 = l * (Lk[3] * OFF[i][0] + Lk[4] * OFF[i][1]);
                const double x2 = l * (Lk[6] * OFF[i][0] + Lk[7] * OFF[i][1]);
                (*pos)[nodeP[3 * k + i]] = Vec3(B.c[0][j] + x0, B.c[1][j] + x1, B.c[2][j] + x2);
                (*vel)[nodeP[3 * k + i]] = Vec3(v0 + wl1 * x2 - wl2 * x1, v1 + wl2 * x0 - wl0 * x2,
                                                v2 + wl0 * x1 - wl1 * x0);
            }
        }
    }
}

void RigidBodyIntegrator::parallel(const std::function<void(int)>& f) {
    if (workers) workers->run(numChunks, f);
    else for (int ch = 0; ch < numChunks; ch++) f(ch);
}

DNAROD_CLONES void RigidBodyIntegrator::nodePoses(int k0, int k1, const vector<Vec3>* pos, double* cOut,
                                                  double* LOut) const {
    // Frames from the (rigid) particles, orthonormalised by Gram-Schmidt so that roundoff cannot accumulate.
    for (int k = k0; k < k1; k++) {
        const Vec3& a0 = (*pos)[nodeP[3 * k]];
        const Vec3& a1 = (*pos)[nodeP[3 * k + 1]];
        const Vec3& a2 = (*pos)[nodeP[3 * k + 2]];
        double* ck = &cOut[3 * k];
        double* Lk = &LOut[9 * k];
        double d1[3], d2[3];
        for (int r = 0; r < 3; r++) {
            ck[r] = (a0[r] + a1[r] + a2[r]) / 3.0;
            d1[r] = 2.0 * a0[r] - a1[r] - a2[r];
            d2[r] = a1[r] - a2[r];
        }
        double nn = 1.0 / sqrt(d1[0] * d1[0] + d1[1] * d1[1] + d1[2] * d1[2]);
        for (int r = 0; r < 3; r++) d1[r] *= nn;
        const double dd = d1[0] * d2[0] + d1[1] * d2[1] + d1[2] * d2[2];
        for (int r = 0; r < 3; r++) d2[r] -= dd * d1[r];
        nn = 1.0 / sqrt(d2[0] * d2[0] + d2[1] * d2[1] + d2[2] * d2[2]);
        for (int r = 0; r < 3; r++) d2[r] *= nn;
        for (int r = 0; r < 3; r++) { Lk[3 * r] = d1[r]; Lk[3 * r + 1] = d2[r]; }
        Lk[2] = d1[1] * d2[2] - d1[2] * d2[1];
        Lk[5] = d1[2] * d2[0] - d1[0] * d2[2];
        Lk[8] = d1[0] * d2[1] - d1[1] * d2[0];
    }
}

int RigidBodyIntegrator::stepAndReport(int reports, int interval, double* out, double* energies, double limit) {
    if (context == nullptr) throw OpenMMException("RigidBodyIntegrator: not bound to a Context");
    const long long stride = (long long) REPORT_STRIDE * getNumNodes();
    for (int j = 0; j < reports; j++) {
        // Between the reports of one call the particles are not written (the kept node state carries the run, as
        // within one step() call); the last report's step writes them.
        deferWrite = !onDevice && j < reports - 1;
        try {
            step(interval);
        } catch (...) {
            deferWrite = false;
            throw;
        }
        deferWrite = false;
        double* e = energies + 6 * j;
        getNodeReport(out + stride * j, e);
        const double E = e[0] + e[1] + e[2] + e[3], K = e[4];
        if (!(e[5] == 1.0 && std::isfinite(E) && std::isfinite(K) && std::fabs(E) + K < limit)) return j;
    }
    return reports;
}

void RigidBodyIntegrator::getNodeReport(double* out, double* energies) {
    if (context == nullptr) throw OpenMMException("RigidBodyIntegrator: not bound to a Context");
    const int n = getNumNodes();
    const vector<Vec3>* pos;
    const vector<Vec3>* vel;
    if (refData != nullptr) {
        pos = ((ReferencePlatform::PlatformData*) refData)->positions;
        vel = ((ReferencePlatform::PlatformData*) refData)->velocities;
    } else {
        context->getPositions(posBuf);
        context->getVelocities(velBuf);
        pos = &posBuf;
        vel = &velBuf;
    }
    if (cacheValid && verifyParticles) {
        cacheValid = particlesMatch(pos, vel);
        verifyParticles = false;
    }
    const bool fromCache = cacheValid && !haveOther && refData != nullptr;
    const double* cc;
    const double* LL;
    const double* FF;
    const double* tt;
    double eOther = 0.0;
    if (fromCache) {
        // The kept node state (what the next step starts from) and its loads, kept for that step.
        const long long version = fused != nullptr ? fused->version : 0;
        if (!(loadsValid && loadsVersion == version)) {
            loads(false);
            loadsValid = true;
            loadsVersion = version;
        }
        cc = c.data(); LL = L.data(); FF = F.data(); tt = tau.data();
    } else {
        loadsValid = false;
        rc.resize(3 * n); rL.resize(9 * n);
        rF.assign(3 * n, 0.0); rtau.assign(3 * n, 0.0);
        nodePoses(0, n, pos, rc.data(), rL.data());
        lastE[0] = lastE[1] = lastE[2] = 0.0;
        if (fused != nullptr) {
            int bad;
            lastE[0] = fused->nodeLoads(rc.data(), rL.data(), rF.data(), rtau.data(), bad);
        }
        if (pairs != nullptr) {
            pairs->nodeForces(rc.data(), rF.data());
            lastE[1] = pairs->lastWca;
            lastE[2] = pairs->lastDh;
        }
        if (haveOther) {
            eOther = context->calcForcesAndEnergy(true, true, otherGroups);
            otherLoads(rc.data(), pos, rF.data(), rtau.data());
        }
        cc = rc.data(); LL = rL.data(); FF = rF.data(); tt = rtau.data();
    }
    const double h = 0.5 * getStepSize();
    const bool half = friction > 0;  // Langevin: the Context reports the stored (half-step) kinetic energy
    double ke = 0.0;
    // Four blocks, each C-contiguous: centres (n, 3), frames (n, 9), velocities (n, 3), angular velocities (n, 3).
    double* oc = out;
    double* oL = out + 3 * (long long) n;
    double* ov = out + 12 * (long long) n;
    double* ow = out + 15 * (long long) n;
    std::memcpy(oc, cc, sizeof(double) * 3 * n);
    std::memcpy(oL, LL, sizeof(double) * 9 * n);
    for (int k = 0; k < n; k++) {
        const double* Lk = LL + 9 * k;
        if (mass[k] == 0.0) {
            for (int a = 0; a < 3; a++) ov[3 * k + a] = ow[3 * k + a] = 0.0;
            continue;
        }
        const double m = mass[k];
        double v[3], pi[3];
        if (fromCache) {
            for (int a = 0; a < 3; a++) { v[a] = cP[3 * k + a] * invMass[k]; pi[a] = cPi[3 * k + a]; }
        } else {
            double h3[3] = {0, 0, 0};
            v[0] = v[1] = v[2] = 0.0;
            for (int i = 0; i < 3; i++) {
                const Vec3& u = (*vel)[nodeP[3 * k + i]];
                v[0] += u[0] / 3.0; v[1] += u[1] / 3.0; v[2] += u[2] / 3.0;
            }
            for (int i = 0; i < 3; i++) {
                const Vec3& u = (*vel)[nodeP[3 * k + i]];
                const Vec3& p = (*pos)[nodeP[3 * k + i]];
                const double x0 = p[0] - cc[3 * k], x1 = p[1] - cc[3 * k + 1], x2 = p[2] - cc[3 * k + 2];
                const double u0 = u[0] - v[0], u1 = u[1] - v[1], u2 = u[2] - v[2];
                h3[0] += x1 * u2 - x2 * u1;
                h3[1] += x2 * u0 - x0 * u2;
                h3[2] += x0 * u1 - x1 * u0;
            }
            for (int a = 0; a < 3; a++) pi[a] = (m / 3.0) * (Lk[a] * h3[0] + Lk[3 + a] * h3[1] + Lk[6 + a] * h3[2]);
        }
        const double iJ[3] = {invJ12[k], invJ12[k], 0.5 * invJ12[k]};
        if (half) {
            ke += 0.5 * m * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
            for (int a = 0; a < 3; a++) ke += 0.5 * pi[a] * pi[a] * iJ[a];
        }
        const double* Fk = FF + 3 * k;
        const double* tk = tt + 3 * k;
        for (int a = 0; a < 3; a++) {
            v[a] += h * Fk[a] * invMass[k];
            pi[a] += h * (Lk[a] * tk[0] + Lk[3 + a] * tk[1] + Lk[6 + a] * tk[2]);
        }
        if (!half) {
            ke += 0.5 * m * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
            for (int a = 0; a < 3; a++) ke += 0.5 * pi[a] * pi[a] * iJ[a];
        }
        for (int a = 0; a < 3; a++) {
            ov[3 * k + a] = v[a];
            ow[3 * k + a] = pi[a] * iJ[a];
        }
    }
    energies[0] = lastE[0];
    energies[1] = lastE[1];
    energies[2] = lastE[2];
    energies[3] = eOther;
    energies[4] = ke;
    // 1 if every node value written is finite (x - x is 0 for finite x, NaN for NaN and inf). Eight independent
    // sums: one running sum is a chain of dependent additions as long as the report, as slow as the rest of it.
    double probe[8] = {0, 0, 0, 0, 0, 0, 0, 0};
    const long long total = (long long) REPORT_STRIDE * n;
    long long i = 0;
    for (; i + 8 <= total; i += 8)
        for (int j = 0; j < 8; j++) probe[j] += out[i + j] - out[i + j];
    for (; i < total; i++) probe[0] += out[i] - out[i];
    double sum = 0.0;
    for (int j = 0; j < 8; j++) sum += probe[j];
    energies[5] = sum == 0.0 ? 1.0 : 0.0;
}

double RigidBodyIntegrator::computeKineticEnergy() {
    // The particles move rigidly, so their kinetic energy is the nodes' 1/2 m v^2 + 1/2 omega^T J omega. The
    // stored velocities are half a step behind the positions; as OpenMM's Verlet integrator does, NVE reports
    // them completed to the positions' time by the half kick of the current forces (Langevin reports them as
    // stored, as LangevinMiddleIntegrator does).
    vector<Vec3> v, p, f;
    context->getVelocities(v);
    const System& system = context->getSystem();
    if (friction > 0) {
        double ke = 0.0;
        for (int i = 0; i < system.getNumParticles(); i++) ke += 0.5 * system.getParticleMass(i) * v[i].dot(v[i]);
        return ke;
    }
    context->getPositions(p);
    context->getForces(f);
    const double h = 0.5 * getStepSize();
    double ke = 0.0;
    const int n = getNumNodes();
    for (int k = 0; k < n; k++) {
        if (mass[k] == 0.0) continue;
        const int* q = &nodeP[3 * k];
        Vec3 cen = (p[q[0]] + p[q[1]] + p[q[2]]) / 3.0;
        Vec3 vel = (v[q[0]] + v[q[1]] + v[q[2]]) / 3.0;
        Vec3 Fk = f[q[0]] + f[q[1]] + f[q[2]];
        Vec3 hl, tl;
        for (int i = 0; i < 3; i++) {
            const Vec3 x = p[q[i]] - cen;
            hl += x.cross(v[q[i]] - vel);
            tl += x.cross(f[q[i]]);
        }
        // Frame from the particles (d1, d2, d3); body components of sum x_i x du_i and of the torque.
        Vec3 d1 = p[q[0]] * 2.0 - p[q[1]] - p[q[2]];
        d1 /= sqrt(d1.dot(d1));
        Vec3 d2 = p[q[1]] - p[q[2]];
        d2 -= d1 * d1.dot(d2);
        d2 /= sqrt(d2.dot(d2));
        const Vec3 d3 = d1.cross(d2);
        const double m = mass[k], l2 = nodeR[k] * nodeR[k];
        const double J[3] = {0.5 * m * l2, 0.5 * m * l2, m * l2};
        const Vec3 dirs[3] = {d1, d2, d3};
        const Vec3 von = vel + Fk * (h / m);
        ke += 0.5 * m * von.dot(von);
        for (int a = 0; a < 3; a++) {
            const double pi = (m / 3.0) * dirs[a].dot(hl) + h * dirs[a].dot(tl);
            ke += 0.5 * pi * pi / J[a];
        }
    }
    return ke;
}

void RigidBodyIntegrator::createCheckpoint(ostream& stream) const {
    // Stream 0 first and a flag byte (bit 0: node state follows; bit 1: the other threads' streams follow it).
    normals[0].save(stream);
    const bool kept = cacheValid && refData != nullptr;
    const char valid = (kept ? 1 : 0) | (numChunks > 1 ? 2 : 0);
    stream.write(&valid, 1);
    if (kept) {
        stream.write((const char*) c.data(), sizeof(double) * c.size());
        stream.write((const char*) L.data(), sizeof(double) * L.size());
        stream.write((const char*) cP.data(), sizeof(double) * cP.size());
        stream.write((const char*) cPi.data(), sizeof(double) * cPi.size());
        // the particles the kept state belongs to (nobody has set them since the last step wrote them)
        const vector<Vec3>& p = *((ReferencePlatform::PlatformData*) refData)->positions;
        const vector<Vec3>& v = *((ReferencePlatform::PlatformData*) refData)->velocities;
        const long long np = (long long) p.size();
        stream.write((const char*) &np, sizeof(np));
        stream.write((const char*) p.data(), sizeof(Vec3) * p.size());
        stream.write((const char*) v.data(), sizeof(Vec3) * v.size());
    }
    if (numChunks > 1) {
        const int extra = numChunks - 1;
        stream.write((const char*) &extra, sizeof(extra));
        for (int ch = 1; ch < numChunks; ch++) normals[ch].save(stream);
    }
}

void RigidBodyIntegrator::loadCheckpoint(istream& stream) {
    normals[0].load(stream);
    char flags = 0;
    stream.read(&flags, 1);
    const bool valid = (flags & 1) != 0;
    if (valid) {
        stream.read((char*) c.data(), sizeof(double) * c.size());
        stream.read((char*) L.data(), sizeof(double) * L.size());
        stream.read((char*) cP.data(), sizeof(double) * cP.size());
        stream.read((char*) cPi.data(), sizeof(double) * cPi.size());
    }
    if (valid) {
        long long np = 0;
        stream.read((char*) &np, sizeof(np));
        lastPos.resize(np);
        lastVel.resize(np);
        stream.read((char*) lastPos.data(), sizeof(Vec3) * lastPos.size());
        stream.read((char*) lastVel.data(), sizeof(Vec3) * lastVel.size());
    }
    // The other chunks' streams (a checkpoint written with another chunk size gives what it has; the rest are
    // reseeded).
    int extra = 0;
    if (flags & 2) stream.read((char*) &extra, sizeof(extra));
    Gaussian scratch;
    for (int ch = 1; ch <= extra; ch++) (ch < numChunks ? normals[ch] : scratch).load(stream);
    for (int ch = extra + 1; ch < numChunks; ch++) normals[ch].seed(streamSeed(baseSeed, ch));
    cacheValid = valid;
    // OpenMM restores the particles apart from this call (and tells the integrator nothing): the first step or
    // report compares them with the ones stored here before it trusts the node state.
    verifyParticles = valid;
    loadsValid = false;
}

void RigidBodyIntegrator::stateChanged(State::DataType changed) {
    // Positions or velocities set by the user (setPositions, setVelocities, setState, a minimizer): the kept node
    // state no longer belongs to the particles. While a loaded checkpoint's check is pending (OpenMM may report
    // the checkpoint's own particles as changed) that check decides: it compares the particles themselves.
    // Parameters change only forces OpenMM evaluates (read every step) or the fused forces' parameters (their
    // version is checked), so they keep it.
    if ((changed == State::Positions || changed == State::Velocities) && !verifyParticles) {
        cacheValid = false;
        loadsValid = false;
    }
}

bool RigidBodyIntegrator::particlesMatch(const vector<Vec3>* pos, const vector<Vec3>* vel) const {
    return pos->size() == lastPos.size() && vel->size() == lastVel.size()
           && std::memcmp(pos->data(), lastPos.data(), sizeof(Vec3) * lastPos.size()) == 0
           && std::memcmp(vel->data(), lastVel.data(), sizeof(Vec3) * lastVel.size()) == 0;
}


} // namespace dnarod
