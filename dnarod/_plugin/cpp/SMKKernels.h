#ifndef DNAROD_SMKKERNELS_H_
#define DNAROD_SMKKERNELS_H_
// The platform kernel interface of SMKForce for platforms that evaluate it on their device (OpenCL, CUDA:
// common/CommonSMKKernel.*). Header-only on purpose: the kernel libraries (libdnarod_opencl.so, ...) are
// loaded by OpenMM as plugin libraries, separately from the Python extension that holds SMKForce, and use
// only SMKForce's inline accessors. Platforms without this kernel (Reference, CPU) evaluate SMKForce as host
// code (SMKForceImpl, OpenMM's CustomCPPForceImpl).
#include "SMKForce.h"
#include "openmm/KernelImpl.h"
#include "openmm/Platform.h"
#include "openmm/System.h"
#include <string>

namespace OpenMM { class ContextImpl; }

namespace dnarod {

class CalcSMKForceKernel : public OpenMM::KernelImpl {
public:
    static std::string Name() { return "DnarodCalcSMKForce"; }
    CalcSMKForceKernel(std::string name, const OpenMM::Platform& platform) : OpenMM::KernelImpl(name, platform) {}
    /** Upload nodes, steps, closure and ds of force. */
    virtual void initialize(const OpenMM::System& system, const SMKForce& force) = 0;
    /** Forces and energy are added on the device; returns 0 (the energy is in the device's energy buffer). */
    virtual double execute(OpenMM::ContextImpl& context, bool includeForces, bool includeEnergy) = 0;
    /** Upload changed step parameters (stiffness, intrinsic strains). */
    virtual void copyParametersToContext(OpenMM::ContextImpl& context, const SMKForce& force) = 0;
};

} // namespace dnarod

#endif
