#ifndef DNAROD_RIGIDBODYINTEGRATOR_H_
#define DNAROD_RIGIDBODYINTEGRATOR_H_
// A constraint-free integrator of rigid base-pair nodes (three particles on an equilateral triangle of
// circumradius l, dnarod.openmm.particles), the symplectic splitting of dnarod.integrators.splitting moved
// into OpenMM: kick of the lab momentum and the body angular momentum, drift of the centre, exact free-rotor
// sub-flows R1(h/2) R2(h/2) R3(h) R2(h/2) R1(h/2) of the frame. Stored velocities are half a step behind the
// positions, as in OpenMM's LangevinMiddleIntegrator (leapfrog form):
//   NVE (friction 0):  V(dt) A(dt)               (= kick-drift-rotor-kick shifted by half a step)
//   Langevin:          V(dt) A(dt/2) O(dt) A(dt/2) (BAOAB in leapfrog form; O acts on the lab momentum with
//                      variance m kT and on each body angular momentum component with variance J_a kT)
// The node state is read from the particles at every step and written back exactly rigid, so the
// integrator keeps no state but its random number generator (checkpointed). Constraints in the System
// are not applied (the triangles stay rigid by construction). Particles of zero mass (clamped nodes) stay put.
// If the System holds a dnarod SMKForce, its node loads are computed here directly (no spreading over
// particles); every other force is evaluated by OpenMM and reduced to node forces and torques.
#include "openmm/Integrator.h"
#include "openmm/Kernel.h"
#include "Random.h"
#include <memory>
#include <random>
#include <string>
#include <vector>

namespace OpenMM { class ContextImpl; }

namespace dnarod {

class SMKForceImpl;
class NodePairForceImpl;

class RigidBodyIntegrator : public OpenMM::Integrator {
public:
    /** stepSize ps, temperature K, friction 1/ps (0: NVE). */
    RigidBodyIntegrator(double stepSize, double temperature = 300.0, double friction = 0.0);
    /** A node carried by particles p0, p1, p2 (triangle circumradius radius, nm); returns its index. */
    int addNode(int p0, int p1, int p2, double radius);
    int getNumNodes() const { return (int) nodeP.size() / 3; }
    double getTemperature() const { return temperature; }
    void setTemperature(double t);
    double getFriction() const { return friction; }
    void setFriction(double f);
    int getRandomNumberSeed() const { return seed; }
    void setRandomNumberSeed(int s) { seed = s; }
    void step(int steps);
    /** True if the SMK step loads are evaluated inside the integrator (the System has an SMKForce). */
    bool usesFusedElasticForce() const { return fused != nullptr; }
    /** True if the node-pair (WCA + Debye-Hueckel) forces are evaluated inside the integrator. */
    bool usesFusedPairForce() const { return pairs != nullptr; }
    /** True if the steps run on the device (OpenCL/CUDA with dnarod's kernel library; every force by OpenMM). */
    bool usesDeviceKernel() const { return onDevice; }
    /** Lanes of the blocked update (internal). */
    static const int BLOCK = 16;
    struct Block {
        double L[9][BLOCK], c[3][BLOCK], P[3][BLOCK], pi[3][BLOCK], iJ[3][BLOCK], im[BLOCK], sP[BLOCK], sPi[3][BLOCK];
    };
protected:
    void initialize(OpenMM::ContextImpl& context);
    void cleanup() {}
    std::vector<std::string> getKernelNames();
    double computeKineticEnergy();
    bool kineticEnergyRequiresForce() const { return friction == 0; }
    void createCheckpoint(std::ostream& stream) const;
    void loadCheckpoint(std::istream& stream);
private:
    void loads(bool needOther);
    void run(int steps);
    void nodePoses(int n, const std::vector<OpenMM::Vec3>* pos);
    double temperature, friction;
    int seed;
    std::vector<int> nodeP;
    std::vector<double> nodeR;
    OpenMM::ContextImpl* context = nullptr;
    void* refData = nullptr;
    OpenMM::Kernel setupKernel;
    std::shared_ptr<OpenMM::Integrator> placeholder;  // ReferencePlatform::PlatformData on the Reference and CPU platforms
    SMKForceImpl* fused = nullptr;
    NodePairForceImpl* pairs = nullptr;
    int otherGroups = 0;
    bool haveOther = false;
    std::vector<double> mass, c, L, F, tau, cP, cPi;
    bool cacheValid = false;
    std::vector<OpenMM::Vec3> lastPos, lastVel;  // the particles as written at the end of the last call
    std::vector<OpenMM::Vec3> posBuf, velBuf, forceBuf;
    std::vector<double> sigP, sigPi;  // per node: sqrt(m), sqrt(J_a)
    std::vector<double> invMass, invJ12;  // per node: 1/m, 1/J1 = 1/J2 = 2/(m l^2) (0 for clamped nodes)
    Gaussian normal;
    Block blk;
    bool onDevice = false;
    OpenMM::Kernel deviceKernel;  // IntegrateRigidBodyStepKernel (RigidBodyKernels.h) when onDevice
};

} // namespace dnarod

#endif
