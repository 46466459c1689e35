#ifndef DNAROD_NODEPAIRFORCEIMPL_H_
#define DNAROD_NODEPAIRFORCEIMPL_H_
// NodePairForce implementation: the same C++ computation on every platform (OpenMM's CustomCPPForceImpl).
// RigidBodyIntegrator calls nodeForces() directly.
#include "NodePairForce.h"
#include "openmm/OpenMMException.h"
#include "openmm/System.h"
#include "openmm/internal/ContextImpl.h"
#include "openmm/internal/CustomCPPForceImpl.h"
#include <algorithm>
#include <vector>

namespace dnarod {

class NodePairForceImpl : public OpenMM::CustomCPPForceImpl {
public:
    NodePairForceImpl(const NodePairForce& owner) : OpenMM::CustomCPPForceImpl(owner), owner(owner) {}
    void initialize(OpenMM::ContextImpl& context) {
        OpenMM::CustomCPPForceImpl::initialize(context);
        particles = owner.particleList();
        const int np = context.getSystem().getNumParticles();
        for (int p : particles)
            if (p < 0 || p >= np) throw OpenMM::OpenMMException("NodePairForce: a node refers to a missing particle");
        n = (int) particles.size() / 3;
        list.setup(owner.params(), n);
        c.resize(3 * n);
        F.resize(3 * n);
    }
    const NodePairForce& getOwner() const { return owner; }
    /** Adds the forces on node centres cc (n*3) to FF; returns the energy. */
    double nodeForces(const double* cc, double* FF) {
        double ew, ed;
        double e = list.evaluate(cc, FF, ew, ed);
        lastWca = owner.lastWca = ew;
        lastDh = owner.lastDh = ed;
        return e;
    }
    double computeForce(OpenMM::ContextImpl& context, const std::vector<OpenMM::Vec3>& positions,
                        std::vector<OpenMM::Vec3>& forces) {
        std::fill(forces.begin(), forces.end(), OpenMM::Vec3());
        for (int k = 0; k < n; k++)
            for (int a = 0; a < 3; a++)
                c[3 * k + a] = (positions[particles[3 * k]][a] + positions[particles[3 * k + 1]][a]
                                + positions[particles[3 * k + 2]][a]) / 3.0;
        std::fill(F.begin(), F.end(), 0.0);
        const double e = nodeForces(c.data(), F.data());
        for (int k = 0; k < n; k++)
            for (int i = 0; i < 3; i++) {
                OpenMM::Vec3& f = forces[particles[3 * k + i]];
                f[0] = F[3 * k] / 3.0; f[1] = F[3 * k + 1] / 3.0; f[2] = F[3 * k + 2] / 3.0;
            }
        return e;
    }
    double lastWca = 0, lastDh = 0;
private:
    const NodePairForce& owner;
    std::vector<int> particles;
    int n = 0;
    NodePairList list;
    std::vector<double> c, F;
};

} // namespace dnarod

#endif
