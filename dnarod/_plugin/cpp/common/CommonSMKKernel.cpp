#include "CommonSMKKernel.h"
#include "CommonSMKKernelSource.h"
#include "openmm/OpenMMException.h"
#include "openmm/common/BondedUtilities.h"
#include "openmm/common/ComputeForceInfo.h"
#include "openmm/common/ContextSelector.h"
#include <cmath>
#include <map>

using namespace OpenMM;
using namespace std;

namespace dnarod {

// Tells the Common platforms which particles the force couples (each step: the six particles of its two nodes),
// so that atom reordering never separates a node from its chain. No two particles or steps are declared
// identical: the chain is one molecule and is never permuted.
class SMKForceInfo : public ComputeForceInfo {
public:
    SMKForceInfo(const SMKForce& force) : force(force) {}
    bool areParticlesIdentical(int particle1, int particle2) { return particle1 == particle2; }
    int getNumParticleGroups() { return force.getNumSteps(); }
    void getParticlesInGroup(int index, vector<int>& particles) {
        const SMKForce::Step& s = force.stepList()[index];
        const SMKForce::Node& a = force.nodeList()[s.left];
        const SMKForce::Node& b = force.nodeList()[s.right];
        particles = {a.p[0], a.p[1], a.p[2], b.p[0], b.p[1], b.p[2]};
    }
    bool areGroupsIdentical(int group1, int group2) { return group1 == group2; }
private:
    const SMKForce& force;
};

// Cayley-limit denominator, as in SMKForce.cpp (largest admissible step rotation pi - 1e-4).
static const double denLimit = 2.0 * (1.0 + cos(M_PI - 1e-4));

void CommonCalcSMKForceKernel::initialize(const System& system, const SMKForce& force) {
    ContextSelector selector(cc);
    const int total = force.getNumSteps();
    // Split the steps over the devices of a multi-device context (each evaluates its share).
    first = cc.getContextIndex() * total / cc.getNumContexts();
    numSteps = (cc.getContextIndex() + 1) * total / cc.getNumContexts() - first;
    if (!(force.getDs() > 0)) throw OpenMMException("SMKForce: ds must be positive");
    const vector<SMKForce::Node>& nodes = force.nodeList();
    const vector<SMKForce::Step>& steps = force.stepList();
    for (const auto& nd : nodes)
        for (int i = 0; i < 3; i++)
            if (nd.p[i] < 0 || nd.p[i] >= system.getNumParticles())
                throw OpenMMException("SMKForce: a node refers to a particle that is not in the System");
    for (const auto& s : steps)
        if (s.left < 0 || s.left >= (int) nodes.size() || s.right < 0 || s.right >= (int) nodes.size())
            throw OpenMMException("SMKForce: a step refers to a node that does not exist");
    if (numSteps == 0) return;
    const bool dbl = cc.getUseDoublePrecision();
    const int realSize = dbl ? sizeof(double) : sizeof(float);
    const string realType = dbl ? "double" : "float";
    params.initialize(cc, 48 * numSteps, realSize, "dnarodSMKParams");
    flags.initialize<int>(cc, numSteps, "dnarodSMKImage");
    globals.initialize(cc, 15, realSize, "dnarodSMKGlobals");
    vector<vector<int> > atoms(numSteps, vector<int>(6));
    vector<int> image(numSteps);
    for (int k = 0; k < numSteps; k++) {
        const SMKForce::Step& s = steps[first + k];
        for (int i = 0; i < 3; i++) {
            atoms[k][i] = nodes[s.left].p[i];
            atoms[k][3 + i] = nodes[s.right].p[i];
        }
        image[k] = s.image ? 1 : 0;
    }
    flags.upload(image);
    const vector<double> Q = force.getClosureQ(), t = force.getClosureT();
    vector<double> g(15);
    for (int i = 0; i < 9; i++) g[i] = Q[i];
    for (int i = 0; i < 3; i++) g[9 + i] = t[i];
    g[12] = force.getDs();
    g[13] = 1.0 / force.getDs();
    g[14] = denLimit;
    globals.upload(g, true);
    uploadParameters(force);
    map<string, string> replacements;
    replacements["PARAMS"] = cc.getBondedUtilities().addArgument(params, realType);
    replacements["FLAGS"] = cc.getBondedUtilities().addArgument(flags, "int");
    replacements["GLOBALS"] = cc.getBondedUtilities().addArgument(globals, realType);
    cc.getBondedUtilities().addInteraction(atoms, cc.replaceStrings(commonSMKSource, replacements),
                                           force.getForceGroup());
    cc.addForce(new SMKForceInfo(force));
}

void CommonCalcSMKForceKernel::uploadParameters(const SMKForce& force) {
    const vector<SMKForce::Node>& nodes = force.nodeList();
    const vector<SMKForce::Step>& steps = force.stepList();
    vector<double> p(48 * numSteps);
    for (int k = 0; k < numSteps; k++) {
        const SMKForce::Step& s = steps[first + k];
        double* q = &p[48 * k];
        for (int i = 0; i < 36; i++) q[i] = s.K[i];
        for (int i = 0; i < 6; i++) q[36 + i] = s.xi0[i];
        const double la = nodes[s.left].radius, lb = nodes[s.right].radius;
        q[42] = 1.0 / (3.0 * la);
        q[43] = 1.0 / (sqrt(3.0) * la);
        q[44] = 1.0 / (la * la);
        q[45] = 1.0 / (3.0 * lb);
        q[46] = 1.0 / (sqrt(3.0) * lb);
        q[47] = 1.0 / (lb * lb);
    }
    params.upload(p, true);
}

double CommonCalcSMKForceKernel::execute(ContextImpl& context, bool includeForces, bool includeEnergy) {
    return 0.0;  // evaluated by BondedUtilities with the other bonded forces
}

void CommonCalcSMKForceKernel::copyParametersToContext(ContextImpl& context, const SMKForce& force) {
    const int total = force.getNumSteps();
    const int f = cc.getContextIndex() * total / cc.getNumContexts();
    const int n = (cc.getContextIndex() + 1) * total / cc.getNumContexts() - f;
    if (f != first || n != numSteps)
        throw OpenMMException("SMKForce.updateParametersInContext: the number of steps changed");
    if (numSteps == 0) return;
    ContextSelector selector(cc);
    uploadParameters(force);
}

} // namespace dnarod
