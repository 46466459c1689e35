#include "RigidBodyIntegrator.h"
#include "SMKForceImpl.h"
#include "openmm/Context.h"
#include "openmm/OpenMMException.h"
#include "openmm/System.h"
#include "openmm/internal/ContextImpl.h"
#include "openmm/reference/ReferencePlatform.h"
#include <cmath>
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

RigidBodyIntegrator::RigidBodyIntegrator(double stepSize, double temperature, double friction)
    : temperature(temperature), friction(friction), seed(0) {
    setStepSize(stepSize);
    setTemperature(temperature);
    setFriction(friction);
    setConstraintTolerance(1e-8);
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
    // Fuse the SMK force if it is integrated here and its nodes are ours.
    fused = nullptr;
    otherGroups = 0;
    haveOther = false;
    const int groups = getIntegrationForceGroups();
    for (ForceImpl* impl : ctx.getForceImpls()) {
        SMKForceImpl* smk = dynamic_cast<SMKForceImpl*>(impl);
        const int g = impl->getOwner().getForceGroup();
        if (!(groups & (1 << g))) continue;
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
        otherGroups |= 1 << g;
        haveOther = true;
    }
    if (fused != nullptr) {
        // Other forces in the SMK force's group are evaluated by OpenMM with it; then do not fuse.
        const int g = fused->getOwner().getForceGroup();
        if (otherGroups & (1 << g)) fused = nullptr;
        if (fused == nullptr) otherGroups |= 1 << g, haveOther = true;
    }
    const string name = ctx.getPlatform().getName();
    refData = (name == "Reference" || name == "CPU") ? ctx.getPlatformData() : nullptr;
    c.resize(3 * n);
    L.resize(9 * n);
    F.resize(3 * n);
    tau.resize(3 * n);
    rng.seed(seed != 0 ? (unsigned long long) seed : (unsigned long long) std::random_device()());
    normal.reset();
}

// Node loads (lab force F, torque tau about the centre) at the current positions, c and L already set.
void RigidBodyIntegrator::loads(bool needOther) {
    std::fill(F.begin(), F.end(), 0.0);
    std::fill(tau.begin(), tau.end(), 0.0);
    if (fused != nullptr) {
        int bad;
        fused->nodeLoads(c.data(), L.data(), F.data(), tau.data(), bad);
    }
    if (!needOther) return;
    context->calcForcesAndEnergy(true, false, otherGroups);
    const vector<Vec3>* f;
    const vector<Vec3>* p;
    if (refData != nullptr) {
        f = ((ReferencePlatform::PlatformData*) refData)->forces;
        p = ((ReferencePlatform::PlatformData*) refData)->positions;
    } else {
        context->getForces(forceBuf);
        f = &forceBuf;
        p = &posBuf;
    }
    const int n = getNumNodes();
    for (int k = 0; k < n; k++) {
        double* Fk = &F[3 * k];
        double* tk = &tau[3 * k];
        for (int i = 0; i < 3; i++) {
            const Vec3& fi = (*f)[nodeP[3 * k + i]];
            const Vec3& pi = (*p)[nodeP[3 * k + i]];
            const double x0 = pi[0] - c[3 * k], x1 = pi[1] - c[3 * k + 1], x2 = pi[2] - c[3 * k + 2];
            Fk[0] += fi[0]; Fk[1] += fi[1]; Fk[2] += fi[2];
            tk[0] += x1 * fi[2] - x2 * fi[1];
            tk[1] += x2 * fi[0] - x0 * fi[2];
            tk[2] += x0 * fi[1] - x1 * fi[0];
        }
    }
}

// Exact free-rotor sub-flow by angle phi about body axis a: rotates frame columns b, d and momenta pb, pd.
static inline void sub(double* Lk, int b, int d, double& pb, double& pd, double phi) {
    const double s = sin(phi), co = cos(phi);
    for (int r = 0; r < 3; r++) {
        const double xb = Lk[3 * r + b], xd = Lk[3 * r + d];
        Lk[3 * r + b] = co * xb + s * xd;
        Lk[3 * r + d] = co * xd - s * xb;
    }
    const double qb = pb, qd = pd;
    pb = co * qb + s * qd;
    pd = co * qd - s * qb;
}

// Free rotor for time h: R1(h/2) R2(h/2) R3(h) R2(h/2) R1(h/2) (dnarod.integrators.splitting.rotor_flow).
static inline void rotor(double* Lk, double* pi, const double* invJ, double h) {
    const double hh = 0.5 * h;
    sub(Lk, 1, 2, pi[1], pi[2], hh * pi[0] * invJ[0]);
    sub(Lk, 2, 0, pi[2], pi[0], hh * pi[1] * invJ[1]);
    sub(Lk, 0, 1, pi[0], pi[1], h * pi[2] * invJ[2]);
    sub(Lk, 2, 0, pi[2], pi[0], hh * pi[1] * invJ[1]);
    sub(Lk, 1, 2, pi[1], pi[2], hh * pi[0] * invJ[0]);
}

void RigidBodyIntegrator::step(int steps) {
    if (context == nullptr) throw OpenMMException("RigidBodyIntegrator: not bound to a Context");
    const int n = getNumNodes();
    const double dt = getStepSize();
    const bool langevin = friction > 0;
    const double cfric = exp(-friction * dt);
    const double kT = KB * temperature;
    const double noise = sqrt(std::max(0.0, 1.0 - cfric * cfric) * kT);
    vector<Vec3>* pos;
    vector<Vec3>* vel;
    for (int s = 0; s < steps; s++) {
        const bool other = haveOther || fused == nullptr;
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
        nodePoses(n, pos);
        loads(other);
        for (int k = 0; k < n; k++) {
            if (mass[k] == 0.0) continue;
            double* ck = &c[3 * k];
            double* Lk = &L[9 * k];
            const double m = mass[k], l = nodeR[k], l2 = l * l;
            const double J[3] = {0.5 * m * l2, 0.5 * m * l2, m * l2};
            const double invJ[3] = {1.0 / J[0], 1.0 / J[1], 1.0 / J[2]};
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
            // sum_i x_i x du_i = L diag(3/2, 3/2, 3) l^2 L^T omega_lab, and pi = J omega_body = m/3 L^T sum(...)
            double P[3], pi[3];
            for (int a = 0; a < 3; a++) {
                P[a] = m * v[a];
                pi[a] = (m / 3.0) * (Lk[a] * h[0] + Lk[3 + a] * h[1] + Lk[6 + a] * h[2]);
            }
            // V: kick by dt.
            const double* Fk = &F[3 * k];
            const double* tk = &tau[3 * k];
            for (int a = 0; a < 3; a++) {
                P[a] += dt * Fk[a];
                pi[a] += dt * (Lk[a] * tk[0] + Lk[3 + a] * tk[1] + Lk[6 + a] * tk[2]);
            }
            if (!langevin) {
                for (int a = 0; a < 3; a++) ck[a] += dt * P[a] / m;
                rotor(Lk, pi, invJ, dt);
            } else {
                const double hdt = 0.5 * dt;
                for (int a = 0; a < 3; a++) ck[a] += hdt * P[a] / m;
                rotor(Lk, pi, invJ, hdt);
                const double sm = noise * sqrt(m);
                for (int a = 0; a < 3; a++) P[a] = cfric * P[a] + sm * normal(rng);
                for (int a = 0; a < 3; a++) pi[a] = cfric * pi[a] + noise * sqrt(J[a]) * normal(rng);
                for (int a = 0; a < 3; a++) ck[a] += hdt * P[a] / m;
                rotor(Lk, pi, invJ, hdt);
            }
            // Write the rigid triangle: p_i = c + l L b_i, u_i = v + (L omega) x (p_i - c).
            double w[3];
            for (int a = 0; a < 3; a++) w[a] = pi[a] * invJ[a];
            const double wl0 = Lk[0] * w[0] + Lk[1] * w[1] + Lk[2] * w[2];
            const double wl1 = Lk[3] * w[0] + Lk[4] * w[1] + Lk[5] * w[2];
            const double wl2 = Lk[6] * w[0] + Lk[7] * w[1] + Lk[8] * w[2];
            for (int i = 0; i < 3; i++) {
                const double x0 = l * (Lk[0] * OFF[i][0] + Lk[1] * OFF[i][1]);
                const double x1 = l * (Lk[3] * OFF[i][0] + Lk[4] * OFF[i][1]);
                const double x2 = l * (Lk[6] * OFF[i][0] + Lk[7] * OFF[i][1]);
                Vec3& p = (*pos)[nodeP[3 * k + i]];
                Vec3& u = (*vel)[nodeP[3 * k + i]];
                p = Vec3(ck[0] + x0, ck[1] + x1, ck[2] + x2);
                u = Vec3(P[0] / m + wl1 * x2 - wl2 * x1, P[1] / m + wl2 * x0 - wl0 * x2, P[2] / m + wl0 * x1 - wl1 * x0);
            }
        }
        if (refData == nullptr) {
            context->setPositions(posBuf);
            context->setVelocities(velBuf);
        }
        context->setTime(context->getTime() + dt);
        context->setStepCount(context->getStepCount() + 1);
    }
}

void RigidBodyIntegrator::nodePoses(int n, const vector<Vec3>* pos) {
    // Frames from the (rigid) particles, orthonormalised by Gram-Schmidt so that roundoff cannot accumulate.
    for (int k = 0; k < n; k++) {
        const Vec3& a0 = (*pos)[nodeP[3 * k]];
        const Vec3& a1 = (*pos)[nodeP[3 * k + 1]];
        const Vec3& a2 = (*pos)[nodeP[3 * k + 2]];
        double* ck = &c[3 * k];
        double* Lk = &L[9 * k];
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

double RigidBodyIntegrator::computeKineticEnergy() {
    // The particles move rigidly, so their kinetic energy is the nodes' 1/2 m v^2 + 1/2 omega^T J omega.
    vector<Vec3> v;
    context->getVelocities(v);
    const System& system = context->getSystem();
    double ke = 0.0;
    for (int p = 0; p < system.getNumParticles(); p++) ke += 0.5 * system.getParticleMass(p) * v[p].dot(v[p]);
    return ke;
}

void RigidBodyIntegrator::createCheckpoint(ostream& stream) const {
    stream << rng << ' ' << normal << ' ';
}

void RigidBodyIntegrator::loadCheckpoint(istream& stream) {
    stream >> rng >> normal;
}

} // namespace dnarod
