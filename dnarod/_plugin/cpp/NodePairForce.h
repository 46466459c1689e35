#ifndef DNAROD_NODEPAIRFORCE_H_
#define DNAROD_NODEPAIRFORCE_H_
// The non-local terms of dnarod.openmm.nonbonded between node centres (centre = mean of a node's three
// particles): WCA repulsion 4 eps [(sigma/r)^12 - (sigma/r)^6] + eps for r < rcWca, and Debye-Hueckel
// aDh exp(-kappa r)/r shifted to zero at rcDh; pairs closer than nExclude+1 along the chain (wrapping for a
// circular chain) do not interact. Forces act on the centres (spread equally over the three particles, no
// torque). Pairs come from a Verlet list (cells of cutoff + skin, rebuilt when a centre has moved more
// than skin/2), summed in a fixed (i, j) order so that results do not depend on when the list was built.
#include "SMKForce.h"
#include "openmm/Force.h"
#include <vector>

namespace dnarod {

class NodePairForce : public OpenMM::Force {
public:
    NodePairForce() {}
    int addNode(int p0, int p1, int p2);
    int getNumNodes() const { return (int) particles.size() / 3; }
    /** eps kJ/mol, sigma nm, rcWca nm (0: off), aDh kJ/mol nm, kappa 1/nm, rcDh nm (0: off). */
    void setParameters(double eps, double sigma, double rcWca, double aDh, double kappa, double rcDh, int nExclude,
                       bool circular);
    void getNodeParticles(int index, int& p0, int& p1, int& p2) const;
    bool usesPeriodicBoundaryConditions() const { return false; }
    /** WCA and Debye-Hueckel energies of the last evaluation in any Context, kJ/mol. */
    double getLastWca() const { return lastWca; }
    double getLastDebyeHuckel() const { return lastDh; }
    mutable double lastWca = 0.0, lastDh = 0.0;
    struct Params { double eps = 0, sigma = 1, rcWca = 0, aDh = 0, kappa = 1, rcDh = 0; int nExclude = 1; bool circular = false; };
    const Params& params() const { return par; }
    const std::vector<int>& particleList() const { return particles; }
protected:
    OpenMM::ForceImpl* createImpl() const;
private:
    std::vector<int> particles;
    Params par;
};

/** Verlet-list evaluation of the pair terms on node centres c (n*3); adds forces to F (n*3). */
class NodePairList {
public:
    void setup(const NodePairForce::Params& p, int n);
    /** Returns E_wca + E_dh; ewca, edh set. */
    double evaluate(const double* c, double* F, double& ewca, double& edh);
    double cutoff() const { return rc; }
private:
    void build(const double* c);
    NodePairForce::Params par;
    int n = 0;
    double rc = 0, skin = 1.0, shiftDh = 0;
    bool built = false;
    std::vector<double> ref;
    std::vector<int> pi, pj;
    std::vector<std::pair<unsigned long long, int> > keys;
};

} // namespace dnarod

#endif
