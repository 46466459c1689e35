#include "CommonRigidBodyKernel.h"
#include "CommonRigidBodyKernelSource.h"
#include "openmm/OpenMMException.h"
#include "openmm/common/ContextSelector.h"
#include "openmm/common/IntegrationUtilities.h"
#include "openmm/internal/ContextImpl.h"
#include <cmath>
#include <map>

using namespace OpenMM;
using namespace std;

namespace dnarod {

// Boltzmann constant in kJ/mol/K (as RigidBodyIntegrator.cpp).
static const double KB = 0.0083144626181532;

// OpenMM's Common platforms may reorder atoms (whole identical molecules) for locality; node particle indices
// are the System's, so they are mapped to the current device positions after every reordering.
class RigidBodyReorderListener : public ComputeContext::ReorderListener {
public:
    RigidBodyReorderListener(CommonIntegrateRigidBodyStepKernel& owner) : owner(owner) {}
    void execute() { owner.placeAtoms(); }
private:
    CommonIntegrateRigidBodyStepKernel& owner;
};

void CommonIntegrateRigidBodyStepKernel::placeAtoms() {
    const vector<int>& order = cc.getAtomIndex();  // order[device position] = System index
    vector<int> where(order.size());
    for (size_t i = 0; i < order.size(); i++) where[order[i]] = (int) i;
    vector<mm_int4> atoms(numNodes);
    for (int k = 0; k < numNodes; k++)
        atoms[k] = mm_int4(where[nodeP[3 * k]], where[nodeP[3 * k + 1]], where[nodeP[3 * k + 2]], 0);
    nodeAtoms.upload(atoms);
}

void CommonIntegrateRigidBodyStepKernel::initialize(const System& system, const vector<int>& nodeP,
                                                    const vector<double>& nodeR, const vector<double>& mass, int seed) {
    cc.initializeContexts();
    ContextSelector selector(cc);
    numNodes = (int) nodeR.size();
    if (numNodes == 0) return;
    this->nodeP = nodeP;
    nodeAtoms.initialize<mm_int4>(cc, numNodes, "dnarodNodeAtoms");
    placeAtoms();
    cc.addReorderListener(new RigidBodyReorderListener(*this));
    const bool mixedDouble = cc.getUseDoublePrecision() || cc.getUseMixedPrecision();
    vector<mm_double4> p(numNodes);
    for (int k = 0; k < numNodes; k++) {
        const double m = mass[k], l = nodeR[k];
        p[k] = m > 0 ? mm_double4(m, l, 1.0 / m, 2.0 / (m * l * l)) : mm_double4(0, l, 0, 0);
    }
    if (mixedDouble) {
        nodeParams.initialize<mm_double4>(cc, numNodes, "dnarodNodeParams");
        nodeParams.upload(p);
    } else {
        vector<mm_float4> pf(numNodes);
        for (int k = 0; k < numNodes; k++) pf[k] = mm_float4((float) p[k].x, (float) p[k].y, (float) p[k].z, (float) p[k].w);
        nodeParams.initialize<mm_float4>(cc, numNodes, "dnarodNodeParams");
        nodeParams.upload(pf);
    }
    cc.getIntegrationUtilities().initRandomNumberGenerator((unsigned int) seed);
    map<string, string> defines;
    defines["PADDED_NUM_ATOMS"] = cc.intToString(cc.getPaddedNumAtoms());
    ComputeProgram program = cc.compileProgram(commonRigidBodySource, defines);
    kernel = program->createKernel("dnarodRigidBodyStep");
}

void CommonIntegrateRigidBodyStepKernel::execute(ContextImpl& context, int steps, double dt, double temperature,
                                                 double friction, int forceGroups) {
    ContextSelector selector(cc);
    IntegrationUtilities& integration = cc.getIntegrationUtilities();
    const bool mixedDouble = cc.getUseDoublePrecision() || cc.getUseMixedPrecision();
    if (!argsSet) {
        argsSet = true;
        kernel->addArg(numNodes);
        kernel->addArg(cc.getPosq());
        kernel->addArg(cc.getUseMixedPrecision() ? cc.getPosqCorrection() : cc.getPosq());
        kernel->addArg(cc.getVelm());
        kernel->addArg(cc.getLongForceBuffer());
        kernel->addArg(nodeAtoms);
        kernel->addArg(nodeParams);
        kernel->addArg(integration.getRandom());
        for (int i = 0; i < 5; i++) kernel->addArg();  // randomIndex, dt, cfric, noise, langevin
    }
    const bool langevin = friction > 0;
    const double cfric = exp(-friction * dt);
    const double noise = sqrt(max(0.0, 1.0 - cfric * cfric) * KB * temperature);
    if (mixedDouble) {
        kernel->setArg(9, dt);
        kernel->setArg(10, cfric);
        kernel->setArg(11, noise);
    } else {
        kernel->setArg(9, (float) dt);
        kernel->setArg(10, (float) cfric);
        kernel->setArg(11, (float) noise);
    }
    kernel->setArg(12, langevin ? 1 : 0);
    for (int s = 0; s < steps; s++) {
        context.updateContextState();
        context.calcForcesAndEnergy(true, false, forceGroups);
        integration.setNextStepSize(dt);
        kernel->setArg(8, langevin ? (unsigned int) integration.prepareRandomNumbers(2 * numNodes) : 0u);
        kernel->execute(numNodes);
        integration.computeVirtualSites();
        cc.setTime(cc.getTime() + dt);
        cc.setStepCount(cc.getStepCount() + 1);
        cc.reorderAtoms();
    }
}

} // namespace dnarod
