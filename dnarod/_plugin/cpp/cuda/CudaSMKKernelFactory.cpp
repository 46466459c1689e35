// Kernel library for OpenMM's CUDA platform (libdnarod_cuda.so): the same Common-compute SMK kernel as on
// OpenCL, registered with the CUDA platform. Built only with -DDNAROD_BUILD_CUDA=ON on a machine with the CUDA
// toolkit (cuda.h) and OpenMM's CUDA platform library (libOpenMMCUDA.so, from openmm-cuda-12).
#include "common/CommonRigidBodyKernel.h"
#include "common/CommonSMKKernel.h"
#include "openmm/KernelFactory.h"
#include "openmm/OpenMMException.h"
#include "openmm/internal/ContextImpl.h"
#include "openmm/cuda/CudaContext.h"
#include "openmm/cuda/CudaPlatform.h"
#include <exception>

using namespace OpenMM;

namespace dnarod {

class CudaSMKKernelFactory : public KernelFactory {
public:
    KernelImpl* createKernelImpl(std::string name, const Platform& platform, ContextImpl& context) const {
        CudaContext& cu = *static_cast<CudaPlatform::PlatformData*>(context.getPlatformData())->contexts[0];
        if (name == CalcSMKForceKernel::Name()) return new CommonCalcSMKForceKernel(name, platform, cu);
        if (name == IntegrateRigidBodyStepKernel::Name()) return new CommonIntegrateRigidBodyStepKernel(name, platform, cu);
        throw OpenMMException("dnarod CUDA kernels: no kernel called " + name);
    }
};

} // namespace dnarod

extern "C" __attribute__((visibility("default"))) void registerPlatforms() {}

extern "C" __attribute__((visibility("default"))) void registerKernelFactories() {
    try {
        Platform& platform = Platform::getPlatformByName("CUDA");
        dnarod::CudaSMKKernelFactory* factory = new dnarod::CudaSMKKernelFactory();
        platform.registerKernelFactory(dnarod::CalcSMKForceKernel::Name(), factory);
        platform.registerKernelFactory(dnarod::IntegrateRigidBodyStepKernel::Name(), factory);
    } catch (std::exception&) {
    }
}

extern "C" __attribute__((visibility("default"))) const char* dnarodKernelsOpenMMVersion() { return DNAROD_OPENMM_VERSION; }
