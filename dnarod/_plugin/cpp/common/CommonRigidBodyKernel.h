#ifndef DNAROD_COMMONRIGIDBODYKERNEL_H_
#define DNAROD_COMMONRIGIDBODYKERNEL_H_
// RigidBodyIntegrator's step on OpenMM's Common compute layer (OpenCL, CUDA): forces from OpenMM on the
// device, then one kernel that updates every node and writes its rigid triangle back (no host copies).
// Random numbers from OpenMM's IntegrationUtilities (checkpointed with the Context).
#include "RigidBodyKernels.h"
#include "openmm/common/ComputeArray.h"
#include "openmm/common/ComputeContext.h"
#include "openmm/common/ComputeKernel.h"

namespace dnarod {

class CommonIntegrateRigidBodyStepKernel : public IntegrateRigidBodyStepKernel {
public:
    CommonIntegrateRigidBodyStepKernel(std::string name, const OpenMM::Platform& platform, OpenMM::ComputeContext& cc)
        : IntegrateRigidBodyStepKernel(name, platform), cc(cc) {}
    void initialize(const OpenMM::System& system, const std::vector<int>& nodeP, const std::vector<double>& nodeR,
                    const std::vector<double>& mass, int seed);
    void execute(OpenMM::ContextImpl& context, int steps, double dt, double temperature, double friction, int forceGroups);
    /** Place the nodes' particles at their current device positions (atoms may be reordered by OpenMM). */
    void placeAtoms();
private:
    OpenMM::ComputeContext& cc;
    std::vector<int> nodeP;
    int numNodes = 0;
    OpenMM::ComputeArray nodeAtoms, nodeParams;
    OpenMM::ComputeKernel kernel;
    bool argsSet = false;
};

} // namespace dnarod

#endif
