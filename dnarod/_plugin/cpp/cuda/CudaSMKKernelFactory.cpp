// Kernel library for OpenMM's CUDA platform (libdnarod_cuda.so): the same Common-compute SMK kernel as on
// OpenCL, registered with the CUDA platform. Built only with -DDNAROD_BUILD_CUDA=ON on a machine with the CUDA
// toolkit (cuda.h) and OpenMM's CUDA platform library (libOpenMMCUDA.so, from openmm-cuda-12).
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
        throw OpenMMException("dnarod CUDA kernels: no kernel called " + name);
    }
};

} // namespace dnarod

extern "C" __attribute__((visibility("default"))) void registerPlatforms() {}

extern "C" __attribute__((visibility("default"))) void registerKernelFactories() {
    try {
        Platform& platform = Platform::getPlatformByName("CUDA");
        platform.registerKernelFactory(dnarod::CalcSMKForceKernel::Name(), new dnarod::CudaSMKKernelFactory());
    } catch (std::exception&) {
    }
}

extern "C" __attribute__((visibility("default"))) const char* dnarodKernelsOpenMMVersion() { return DNAROD_OPENMM_VERSION; }
