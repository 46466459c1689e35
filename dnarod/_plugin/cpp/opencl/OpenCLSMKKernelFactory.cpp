// Kernel library for OpenMM's OpenCL platform (libdnarod_opencl.so): registers the Common-compute SMK force and
// rigid-body step kernels with the OpenCL platform. dnarod.openmm.plugin loads it with openmm.Platform.loadPluginLibrary, which calls
// registerPlatforms() and registerKernelFactories() below.
#include "common/CommonRigidBodyKernel.h"
#include "common/CommonSMKKernel.h"
#include "openmm/KernelFactory.h"
#include "openmm/OpenMMException.h"
#include "openmm/internal/ContextImpl.h"
#include "openmm/opencl/OpenCLContext.h"
#include "openmm/opencl/OpenCLPlatform.h"
#include <exception>

using namespace OpenMM;

namespace dnarod {

class OpenCLSMKKernelFactory : public KernelFactory {
public:
    KernelImpl* createKernelImpl(std::string name, const Platform& platform, ContextImpl& context) const {
        OpenCLContext& cl = *static_cast<OpenCLPlatform::PlatformData*>(context.getPlatformData())->contexts[0];
        if (name == CalcSMKForceKernel::Name()) return new CommonCalcSMKForceKernel(name, platform, cl);
        if (name == IntegrateRigidBodyStepKernel::Name()) return new CommonIntegrateRigidBodyStepKernel(name, platform, cl);
        throw OpenMMException("dnarod OpenCL kernels: no kernel called " + name);
    }
};

} // namespace dnarod

// Defined (empty) so that OpenMM's lookup of this symbol does not find the OpenCL platform library's own.
extern "C" __attribute__((visibility("default"))) void registerPlatforms() {}

extern "C" __attribute__((visibility("default"))) void registerKernelFactories() {
    try {
        Platform& platform = Platform::getPlatformByName("OpenCL");
        dnarod::OpenCLSMKKernelFactory* factory = new dnarod::OpenCLSMKKernelFactory();
        platform.registerKernelFactory(dnarod::CalcSMKForceKernel::Name(), factory);
        platform.registerKernelFactory(dnarod::IntegrateRigidBodyStepKernel::Name(), factory);
    } catch (std::exception&) {
        // no OpenCL platform in this process: nothing to register
    }
}

// Version of OpenMM the library was compiled against (checked by dnarod.openmm.plugin before loading it).
extern "C" __attribute__((visibility("default"))) const char* dnarodKernelsOpenMMVersion() { return DNAROD_OPENMM_VERSION; }
