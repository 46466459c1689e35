#ifndef DNAROD_SMKFORCE_H_
#define DNAROD_SMKFORCE_H_
// The SMK step energy of the dnarod rod model (exact Cayley strains, full 6x6 stiffness per step,
// optional screw closure of a circular chain) as an OpenMM Force acting on rigid base-pair nodes.
// Each node is carried by three particles (p0, p1, p2) on an equilateral triangle of circumradius l in
// the d1-d2 plane (dnarod.openmm.particles):
//   centre c = (p0 + p1 + p2)/3,  d1 = (2 p0 - p1 - p2)/(3 l),  d2 = (p1 - p2)/(sqrt(3) l),  d3 = d1 x d2.
// Step k joins nodes a and b: R = L_a^T L_b, e = c_b - c_a,
//   Omega = (2/ds) axial(R - R^T)/(1 + tr R),  Gamma = L_a^T e / ds,
//   E_k = ds/2 (xi - xi0)^T K (xi - xi0),  xi = (Omega, Gamma).
// Node loads are the exact analytic ones of dnarod.core.energy (docs/formulation.md §4); each node's force F and torque tau
// are spread over its particles as F/3 + a x x_i with a = A^-1 tau (A the triangle's second-moment tensor).
#include "openmm/Force.h"
#include "openmm/Context.h"
#include <vector>

// Hot loops are compiled twice, for AVX2+FMA (x86-64-v3) and the baseline; the loader picks one at run time
// (GCC/Clang function multi-versioning), so the built library still runs on any x86-64.
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__)) && !defined(DNAROD_NO_CLONES)
#define DNAROD_CLONES __attribute__((target_clones("arch=x86-64-v3", "default")))
#else
#define DNAROD_CLONES
#endif

namespace dnarod {

class SMKForce : public OpenMM::Force {
public:
    SMKForce();
    /** Add a node carried by particles p0, p1, p2 with triangle circumradius radius (nm); returns its index. */
    int addNode(int p0, int p1, int p2, double radius);
    /** Add a step from node left to node right (right is the closure image of node `right` if image is true).
     *  stiffness: 36 values (row-major 6x6, kJ/mol units of dnarod), intrinsic: 6 values (Omega0 1/nm, Gamma0). */
    int addStep(int left, int right, const std::vector<double>& stiffness, const std::vector<double>& intrinsic,
                bool image = false);
    void setStepParameters(int index, const std::vector<double>& stiffness, const std::vector<double>& intrinsic);
    void getStepParameters(int index, int& left, int& right, std::vector<double>& stiffness,
                           std::vector<double>& intrinsic, bool& image) const;
    void getNode(int index, int& p0, int& p1, int& p2, double& radius) const;
    int getNumNodes() const { return (int) nodes.size(); }
    int getNumSteps() const { return (int) steps.size(); }
    void setDs(double ds_) { ds = ds_; }
    double getDs() const { return ds; }
    /** Screw closure: image of node i is (Q L_i, Q c_i + t); Q row-major 3x3, t in nm. */
    void setClosure(const std::vector<double>& Q, const std::vector<double>& t);
    std::vector<double> getClosureQ() const { return closureQ; }
    std::vector<double> getClosureT() const { return closureT; }
    /** Push changed step parameters (setStepParameters) into a Context. */
    void updateParametersInContext(OpenMM::Context& context);
    bool usesPeriodicBoundaryConditions() const { return false; }
    /** True if context evaluates this force with a device kernel (OpenCL/CUDA), false for host code. */
    bool usesDeviceKernel(OpenMM::Context& context);
    /** Energy of the last host evaluation in any Context (kJ/mol; NaN at the Cayley limit; not updated by a
     *  device kernel: read the force group's energy from the Context there). */
    double getLastEnergy() const { return lastEnergy; }
    mutable double lastEnergy = 0.0;

    struct Node { int p[3]; double radius; };
    struct Step { int left, right; bool image; double K[36]; double xi0[6]; };
    const std::vector<Node>& nodeList() const { return nodes; }
    const std::vector<Step>& stepList() const { return steps; }
protected:
    OpenMM::ForceImpl* createImpl() const;
private:
    std::vector<Node> nodes;
    std::vector<Step> steps;
    double ds;
    std::vector<double> closureQ, closureT;
};

/** Energy and node loads of a chain (the analytic loads of dnarod.energy); F and tau (lab) are added to.
 *  Returns the energy, or NaN if a step rotation is at/beyond the Cayley limit (badStep set to it). */
double chainLoads(const std::vector<SMKForce::Step>& steps, double ds, const double* Q, const double* t,
                  const double* centres, const double* frames, double* F, double* tau, int& badStep);

/** chainLoads over steps [begin, end) only; if carryF is given, the loads on the right node of step end - 1
 *  are written to carryF, carryT (3 each) instead of being added to F, tau. The carry is zeroed first. */
double chainLoadsRange(const std::vector<SMKForce::Step>& steps, int begin, int end, double ds, const double* Q,
                       const double* t, const double* centres, const double* frames, double* F, double* tau,
                       double* carryF, double* carryT, int& badStep);

/** Centres (n*3) and frames (n*9, row-major, directors as columns) of the nodes from particle positions. */
void nodePoses(const std::vector<SMKForce::Node>& nodes, const std::vector<OpenMM::Vec3>& positions,
               double* centres, double* frames);

/** Version of OpenMM this library was compiled against (from OpenMM's headers). */
const char* builtAgainstOpenMM();

} // namespace dnarod

#endif
