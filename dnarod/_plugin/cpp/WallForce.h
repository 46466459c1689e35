#ifndef DNAROD_WALLFORCE_H_
#define DNAROD_WALLFORCE_H_
// The two planar walls of a magnetic-tweezers member (dnarod.openmm.walls), on particles' z coordinates:
//   surface: E = kSurface/2 min(0, z_p - zSurface)^2 for every surface particle p (a fixed plane);
//   bead:    E = kBead/2 max(0, z_p - z_c)^2 for every bead particle p, z_c the mean z of the bead node's three
//            particles (a plane that moves with the pulled node; its share of the force is spread equally over
//            the three).
// The same energies and forces as the CustomExternalForce / CustomCentroidBondForce pair it replaces, for a
// fraction of the cost: one pass over the particles instead of a Lepton expression (and its derivatives) per
// particle and per bond. Evaluated in C++ on the host on every platform (OpenMM's CustomCPPForceImpl).
#include "openmm/Force.h"
#include <vector>

namespace dnarod {

class WallForce : public OpenMM::Force {
public:
    WallForce() {}
    /** Surface plane z (nm) and the two stiffnesses (kJ/mol/nm^2). */
    void setParameters(double zSurface, double kSurface, double kBead);
    double getSurfaceZ() const { return zSurface; }
    double getSurfaceK() const { return kSurface; }
    double getBeadK() const { return kBead; }
    int addSurfaceParticle(int p);
    int addBeadParticle(int p);
    /** The three particles whose mean z is the bead plane. */
    void setBeadNode(int p0, int p1, int p2);
    int getNumSurfaceParticles() const { return (int) surface.size(); }
    int getNumBeadParticles() const { return (int) bead.size(); }
    bool usesPeriodicBoundaryConditions() const { return false; }
    /** Surface and bead energies of the last evaluation in any Context, kJ/mol. */
    double getLastSurface() const { return lastSurface; }
    double getLastBead() const { return lastBead; }
    mutable double lastSurface = 0.0, lastBead = 0.0;
    const std::vector<int>& surfaceList() const { return surface; }
    const std::vector<int>& beadList() const { return bead; }
    const std::vector<int>& beadNode() const { return node; }
protected:
    OpenMM::ForceImpl* createImpl() const;
private:
    double zSurface = 0.0, kSurface = 0.0, kBead = 0.0;
    std::vector<int> surface, bead, node;
};

} // namespace dnarod

#endif
