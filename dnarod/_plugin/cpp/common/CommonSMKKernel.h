#ifndef DNAROD_COMMONSMKKERNEL_H_
#define DNAROD_COMMONSMKKERNEL_H_
// The SMK force on OpenMM's Common compute layer (one implementation for OpenCL and CUDA): one bonded
// interaction per rod step over the six particles of its two nodes, added to OpenMM's BondedUtilities, so it
// runs on the device inside OpenMM's own bonded-force kernel (no host copies per step). Compiled into each
// platform's kernel library (opencl/, cuda/), since the Common layer's code lives in each platform library.
#include "SMKKernels.h"
#include "openmm/common/ComputeArray.h"
#include "openmm/common/ComputeContext.h"

namespace dnarod {

class CommonCalcSMKForceKernel : public CalcSMKForceKernel {
public:
    CommonCalcSMKForceKernel(std::string name, const OpenMM::Platform& platform, OpenMM::ComputeContext& cc)
        : CalcSMKForceKernel(name, platform), cc(cc) {}
    void initialize(const OpenMM::System& system, const SMKForce& force);
    double execute(OpenMM::ContextImpl& context, bool includeForces, bool includeEnergy);
    void copyParametersToContext(OpenMM::ContextImpl& context, const SMKForce& force);
private:
    void uploadParameters(const SMKForce& force);
    OpenMM::ComputeContext& cc;
    int first = 0, numSteps = 0;
    OpenMM::ComputeArray params, flags, globals;
};

} // namespace dnarod

#endif
