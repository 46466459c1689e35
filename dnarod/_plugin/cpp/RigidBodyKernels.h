#ifndef DNAROD_RIGIDBODYKERNELS_H_
#define DNAROD_RIGIDBODYKERNELS_H_
// Platform kernel interface of RigidBodyIntegrator's step on a device (OpenCL, CUDA: common/
// CommonRigidBodyKernel.*). Header-only, like SMKKernels.h: the kernel libraries are separate shared objects.
// Where a platform offers this kernel, RigidBodyIntegrator hands it whole steps (forces from OpenMM on the
// device, the node update on the device); elsewhere it runs its host code.
#include "openmm/KernelImpl.h"
#include "openmm/Platform.h"
#include "openmm/System.h"
#include <string>
#include <vector>

namespace OpenMM { class ContextImpl; }

namespace dnarod {

class IntegrateRigidBodyStepKernel : public OpenMM::KernelImpl {
public:
    static std::string Name() { return "DnarodIntegrateRigidBodyStep"; }
    IntegrateRigidBodyStepKernel(std::string name, const OpenMM::Platform& platform) : OpenMM::KernelImpl(name, platform) {}
    /** nodeP: 3 particles per node; nodeR: circumradius per node (nm); mass: node mass (amu, 0 = clamped). */
    virtual void initialize(const OpenMM::System& system, const std::vector<int>& nodeP, const std::vector<double>& nodeR,
                            const std::vector<double>& mass, int seed) = 0;
    /** Run steps: V(dt) A(dt) for friction 0, V(dt) A(dt/2) O(dt) A(dt/2) otherwise (ps, K, 1/ps). */
    virtual void execute(OpenMM::ContextImpl& context, int steps, double dt, double temperature, double friction,
                         int forceGroups) = 0;
};

} // namespace dnarod

#endif
