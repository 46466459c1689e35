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
// The particles are written back exactly rigid. With only fused forces on the Reference/CPU platforms the node
// state of the last step is kept between calls (checkpointed with the random number generator, dropped when the
// Context's positions or velocities are set: stateChanged); otherwise it is read from the particles every step. Constraints in the System
// are not applied (the triangles stay rigid by construction). Particles of zero mass (clamped nodes) stay put.
// If the System holds a dnarod SMKForce, its node loads are computed here directly (no spreading over
// particles); every other force is evaluated by OpenMM and reduced to node forces and torques.
#include "openmm/Integrator.h"
#include "openmm/Kernel.h"
#include "openmm/State.h"
#include "Random.h"
#include <functional>
#include <memory>
#include <random>
#include <string>
#include <vector>

namespace OpenMM { class ContextImpl; }

namespace dnarod {

class SMKForceImpl;
class NodePairForceImpl;
class Workers;

class RigidBodyIntegrator : public OpenMM::Integrator {
public:
    /** stepSize ps, temperature K, friction 1/ps (0: NVE). */
    RigidBodyIntegrator(double stepSize, double temperature = 300.0, double friction = 0.0);
    ~RigidBodyIntegrator();
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
    /** Threads the node update and the SMK loads run on in the bound Context: the CPU platform's Threads
     *  property, at most one per chunk of nodes (1 on other platforms). The work is split into chunks of
     *  getNodesPerChunk() nodes, each with its own random-number stream, whichever thread runs it: results do
     *  not depend on the number of threads. */
    int getNumThreads() const { return numThreads; }
    /** Nodes per chunk (default 1024, a multiple of 16; set before creating the Context). */
    int getNodesPerChunk() const { return chunkNodes; }
    void setNodesPerChunk(int m);
    /** Number of doubles per node written by getNodeReport. */
    static const int REPORT_STRIDE = 18;
    /** The node state at the current positions for reporters, without an OpenMM State: in out (n*18 doubles),
     *  four C-contiguous blocks one after the other: the centres c (n, 3, nm), the frames L (n, 9, row-major,
     *  directors as columns), the on-step centre velocities (n, 3, lab, nm/ps) and the on-step angular velocities
     *  (n, 3, body frame, rad/ps), i.e. the stored
     *  half-step velocities completed by the half kick dt/2 of the current loads (zero for clamped nodes);
     *  energies (6): the fused SMK energy, the fused WCA and Debye-Hueckel energies, the energy of every force
     *  OpenMM evaluates for this integrator (all kJ/mol), the kinetic energy as the Context reports it
     *  (computeKineticEnergy), and 1 if every value written to out is finite (else 0). After a step with only fused forces this reads the kept node state, and the
     *  loads computed here are the ones the next step starts from (they are not computed twice). */
    void getNodeReport(double* out, double* energies);
    /** reports times: step(interval), then getNodeReport into out + j * n * REPORT_STRIDE and energies + 6 j;
     *  returns the number of healthy reports (all of them, or the index of the first whose values are not all
     *  finite or whose |potential| + kinetic energy reaches limit, kJ/mol, where it stops). Equal, bit for bit,
     *  to the same calls made one by one; the particles are written after the last report only (and at a stop,
     *  not at all: the caller resets the state). */
    int stepAndReport(int reports, int interval, double* out, double* energies, double limit);
    /** True if the steps run on the device (OpenCL/CUDA with dnarod's kernel library; every force by OpenMM). */
    bool usesDeviceKernel() const { return onDevice; }
    /** Lanes of the blocked update (internal). */
    static const int BLOCK = 16;
    struct Block {
        double L[9][BLOCK], c[3][BLOCK], P[3][BLOCK], pi[3][BLOCK], iJ[3][BLOCK], im[BLOCK], sP[BLOCK], sPi[3][BLOCK];
    };
protected:
    void initialize(OpenMM::ContextImpl& context);
    void cleanup();
    std::vector<std::string> getKernelNames();
    double computeKineticEnergy();
    bool kineticEnergyRequiresForce() const { return friction == 0; }
    void createCheckpoint(std::ostream& stream) const;
    void loadCheckpoint(std::istream& stream);
    /** Called by the Context when the user sets positions, velocities or parameters (Context.setPositions,
     *  setVelocities, setState, setParameter): set positions or velocities drop the kept node state. */
    void stateChanged(OpenMM::State::DataType changed);
private:
    void loads(bool needOther);
    void loadsRange(int t);
    void run(int steps);
    void update(int t, std::vector<OpenMM::Vec3>* pos, std::vector<OpenMM::Vec3>* vel, bool useCache, bool write);
    void nodePoses(int k0, int k1, const std::vector<OpenMM::Vec3>* pos, double* cOut, double* LOut) const;
    void parallel(const std::function<void(int)>& f);
    void chunkSteps(int ch, int& begin, int& end) const;
    void otherLoads(const double* cc, const std::vector<OpenMM::Vec3>* pos, double* FF, double* tt);
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
    bool deferWrite = false;  // stepAndReport: leave the particles to the last report's step
    // F, tau (and lastE: SMK, WCA, DH energies) hold the fused loads at the kept c, L (computed by getNodeReport);
    // the next step starts from them. loadsVersion: the SMKForce parameter version they were computed with.
    bool loadsValid = false;
    long long loadsVersion = -1;
    double lastE[3] = {0, 0, 0};
    std::vector<double> rc, rL, rF, rtau;  // getNodeReport's node state read from the particles
    // The particles of a loaded checkpoint's kept node state: the first step or report after loadCheckpoint
    // checks that the Context holds them (verifyParticles) before it trusts the node state.
    std::vector<OpenMM::Vec3> lastPos, lastVel;
    bool verifyParticles = false;
    bool particlesMatch(const std::vector<OpenMM::Vec3>* pos, const std::vector<OpenMM::Vec3>* vel) const;
    std::vector<OpenMM::Vec3> posBuf, velBuf, forceBuf;
    std::vector<double> sigP, sigPi;  // per node: sqrt(m), sqrt(J_a)
    std::vector<double> invMass, invJ12;  // per node: 1/m, 1/J1 = 1/J2 = 2/(m l^2) (0 for clamped nodes)
    // Chunks: node range [chunkStart[c], chunkStart[c+1]) (whole blocks) and the SMK steps starting in it, its
    // own Gaussian stream (stream 0 is the one of a single chunk), the loads on the right node of its last step
    // (carry, 6 doubles) and its part of the SMK energy. Threads claim chunks (Workers).
    int numThreads = 1, chunkNodes = 1024, numChunks = 1;
    bool chainRanges = false;
    uint64_t baseSeed = 0;
    std::unique_ptr<Workers> workers;
    std::vector<int> chunkStart;
    std::vector<Gaussian> normals;
    std::vector<double> carry, partE;
    // per-step constants for update()
    double stepDt = 0, stepCfric = 0, stepNoise = 0;
    bool onDevice = false;
    OpenMM::Kernel deviceKernel;  // IntegrateRigidBodyStepKernel (RigidBodyKernels.h) when onDevice
};

} // namespace dnarod

#endif
