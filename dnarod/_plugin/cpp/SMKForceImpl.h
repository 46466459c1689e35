#ifndef DNAROD_SMKFORCEIMPL_H_
#define DNAROD_SMKFORCEIMPL_H_
// The SMKForce implementation: host C++ on every platform (OpenMM's CustomCPPForceImpl), or, where the
// platform has a device kernel for it (CalcSMKForceKernel: OpenCL, CUDA when dnarod's kernel library for it is
// loaded), that kernel, which keeps positions and forces on the device.
// RigidBodyIntegrator calls nodeLoads() directly to skip spreading the loads over particles.
#include "SMKForce.h"
#include "SMKKernels.h"
#include "openmm/OpenMMException.h"
#include "openmm/System.h"
#include "openmm/internal/ContextImpl.h"
#include "openmm/internal/CustomCPPForceImpl.h"
#include <algorithm>
#include <vector>

namespace dnarod {

class SMKForceImpl : public OpenMM::CustomCPPForceImpl {
public:
    SMKForceImpl(const SMKForce& owner) : OpenMM::CustomCPPForceImpl(owner), owner(owner) {}
    void initialize(OpenMM::ContextImpl& context) {
        const OpenMM::System& system = context.getSystem();
        steps = owner.stepList();
        nodes = owner.nodeList();
        ds = owner.getDs();
        if (!(ds > 0)) throw OpenMM::OpenMMException("SMKForce: ds must be positive");
        std::vector<double> q = owner.getClosureQ(), tt = owner.getClosureT();
        for (int i = 0; i < 9; i++) Q[i] = q[i];
        for (int i = 0; i < 3; i++) t[i] = tt[i];
        for (const auto& nd : nodes)
            for (int i = 0; i < 3; i++)
                if (nd.p[i] < 0 || nd.p[i] >= system.getNumParticles())
                    throw OpenMM::OpenMMException("SMKForce: a node refers to a particle that is not in the System");
        for (const auto& s : steps)
            if (s.left < 0 || s.left >= (int) nodes.size() || s.right < 0 || s.right >= (int) nodes.size())
                throw OpenMM::OpenMMException("SMKForce: a step refers to a node that does not exist");
        c.resize(3 * nodes.size());
        L.resize(9 * nodes.size());
        F.resize(3 * nodes.size());
        tau.resize(3 * nodes.size());
        const std::vector<std::string> names = {CalcSMKForceKernel::Name()};
        onDevice = context.getPlatform().supportsKernels(names);
        if (onDevice) {
            deviceKernel = context.getPlatform().createKernel(CalcSMKForceKernel::Name(), context);
            deviceImpl().initialize(system, owner);
        } else {
            OpenMM::CustomCPPForceImpl::initialize(context);
        }
    }
    /** True if this Context evaluates the force with a device kernel (no host copies). */
    bool usesDeviceKernel() const { return onDevice; }
    double calcForcesAndEnergy(OpenMM::ContextImpl& context, bool includeForces, bool includeEnergy, int groups) {
        if (!onDevice) return OpenMM::CustomCPPForceImpl::calcForcesAndEnergy(context, includeForces, includeEnergy, groups);
        if ((groups & (1 << owner.getForceGroup())) == 0) return 0.0;
        return deviceImpl().execute(context, includeForces, includeEnergy);
    }
    const SMKForce& getOwner() const { return owner; }
    double computeForce(OpenMM::ContextImpl& context, const std::vector<OpenMM::Vec3>& positions, std::vector<OpenMM::Vec3>& forces) {
        const size_t n = nodes.size();
        // OpenMM hands over the same force buffer every call without clearing it.
        std::fill(forces.begin(), forces.end(), OpenMM::Vec3());
        nodePoses(nodes, positions, c.data(), L.data());
        std::fill(F.begin(), F.end(), 0.0);
        std::fill(tau.begin(), tau.end(), 0.0);
        int bad;
        double E = chainLoads(steps, ds, Q, t, c.data(), L.data(), F.data(), tau.data(), bad);
        for (size_t k = 0; k < n; k++) {
            // a = A^-1 tau with A = l^2 L diag(3/2, 3/2, 3) L^T for the equilateral triangle.
            const double* Lk = L.data() + 9 * k;
            const double* tk = tau.data() + 3 * k;
            const double l2 = nodes[k].radius * nodes[k].radius;
            const double b0 = (Lk[0] * tk[0] + Lk[3] * tk[1] + Lk[6] * tk[2]) / (1.5 * l2);
            const double b1 = (Lk[1] * tk[0] + Lk[4] * tk[1] + Lk[7] * tk[2]) / (1.5 * l2);
            const double b2 = (Lk[2] * tk[0] + Lk[5] * tk[1] + Lk[8] * tk[2]) / (3.0 * l2);
            const double a0 = Lk[0] * b0 + Lk[1] * b1 + Lk[2] * b2;
            const double a1 = Lk[3] * b0 + Lk[4] * b1 + Lk[5] * b2;
            const double a2 = Lk[6] * b0 + Lk[7] * b1 + Lk[8] * b2;
            const double* ck = c.data() + 3 * k;
            const double* Fk = F.data() + 3 * k;
            for (int i = 0; i < 3; i++) {
                const OpenMM::Vec3& p = positions[nodes[k].p[i]];
                const double x0 = p[0] - ck[0], x1 = p[1] - ck[1], x2 = p[2] - ck[2];
                OpenMM::Vec3& f = forces[nodes[k].p[i]];
                f[0] += Fk[0] / 3.0 + a1 * x2 - a2 * x1;
                f[1] += Fk[1] / 3.0 + a2 * x0 - a0 * x2;
                f[2] += Fk[2] / 3.0 + a0 * x1 - a1 * x0;
            }
        }
        lastBadStep = bad;
        owner.lastEnergy = E;
        return E;
    }
    void updateParametersInContext(OpenMM::ContextImpl& context) {
        const std::vector<SMKForce::Step>& s = owner.stepList();
        if (s.size() != steps.size()) throw OpenMM::OpenMMException("SMKForce.updateParametersInContext: the number of steps changed");
        for (size_t k = 0; k < s.size(); k++)
            if (s[k].left != steps[k].left || s[k].right != steps[k].right || s[k].image != steps[k].image)
                throw OpenMM::OpenMMException("SMKForce.updateParametersInContext: the nodes of a step changed");
        steps = s;
        version++;
        if (onDevice) deviceImpl().copyParametersToContext(context, owner);
        context.systemChanged();
    }
    std::vector<std::pair<int, int> > getBondedParticles() const {
        std::vector<std::pair<int, int> > b;
        for (const auto& s : steps) b.push_back(std::make_pair(nodes[s.left].p[0], nodes[s.right].p[0]));
        return b;
    }
    /** Energy and node loads (added to F, tau; lab) at node poses c (n*3), L (n*9). */
    double nodeLoads(const double* cc, const double* LL, double* FF, double* tt, int& bad) const {
        return chainLoads(steps, ds, Q, t, cc, LL, FF, tt, bad);
    }
    /** nodeLoads over steps [begin, end) with the right loads of step end - 1 in carryF, carryT (see
     *  chainLoadsRange); for threads working on disjoint ranges of a chain. */
    double nodeLoadsRange(int begin, int end, const double* cc, const double* LL, double* FF, double* tt,
                          double* carryF, double* carryT, int& bad) const {
        return chainLoadsRange(steps, begin, end, ds, Q, t, cc, LL, FF, tt, carryF, carryT, bad);
    }
    /** True if step k joins node k to node k + 1 for every k < n - 1 and a last step, if any, is the closure
     *  n - 1 -> image of 0 (then ranges of steps touch disjoint nodes except at their ends). */
    bool isChain() const {
        const int n = (int) nodes.size(), m = (int) steps.size();
        if (m < n - 1 || m > n) return false;
        for (int k = 0; k < n - 1; k++)
            if (steps[k].left != k || steps[k].right != k + 1 || steps[k].image) return false;
        return m == n - 1 || (steps[n - 1].left == n - 1 && steps[n - 1].right == 0);
    }
    int numSteps() const { return (int) steps.size(); }
    void stepNodes(int k, int& left, int& right) const { left = steps[k].left; right = steps[k].right; }
    int lastBadStep = -1;
    /** Incremented whenever the step parameters change (updateParametersInContext). */
    long long version = 0;
private:
    // The kernel library is a separate shared object (loaded by OpenMM), so the impl is reached by its fixed
    // kernel name rather than a dynamic_cast across libraries.
    CalcSMKForceKernel& deviceImpl() { return static_cast<CalcSMKForceKernel&>(deviceKernel.getImpl()); }
    bool onDevice = false;
    OpenMM::Kernel deviceKernel;
    const SMKForce& owner;
    std::vector<SMKForce::Step> steps;
    std::vector<SMKForce::Node> nodes;
    double ds;
    double Q[9], t[3];
    std::vector<double> c, L, F, tau;
};

} // namespace dnarod

#endif
