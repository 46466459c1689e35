#include "WallForce.h"
#include "openmm/OpenMMException.h"
#include "openmm/System.h"
#include "openmm/internal/ContextImpl.h"
#include "openmm/internal/CustomCPPForceImpl.h"
#include <algorithm>
#include <cmath>

using namespace OpenMM;
using namespace std;

namespace dnarod {

void WallForce::setParameters(double z, double ks, double kb) {
    if (!std::isfinite(z) || !(ks >= 0) || !(kb >= 0) || !std::isfinite(ks) || !std::isfinite(kb))
        throw OpenMMException("WallForce: invalid parameters (finite surface z, stiffnesses >= 0)");
    zSurface = z; kSurface = ks; kBead = kb;
}

int WallForce::addSurfaceParticle(int p) {
    surface.push_back(p);
    return (int) surface.size() - 1;
}

int WallForce::addBeadParticle(int p) {
    bead.push_back(p);
    return (int) bead.size() - 1;
}

void WallForce::setBeadNode(int p0, int p1, int p2) { node = {p0, p1, p2}; }

class WallForceImpl : public CustomCPPForceImpl {
public:
    WallForceImpl(const WallForce& owner) : CustomCPPForceImpl(owner), owner(owner) {}
    const WallForce& getOwner() const { return owner; }
    void initialize(ContextImpl& context) {
        CustomCPPForceImpl::initialize(context);
        const int np = context.getSystem().getNumParticles();
        surface = owner.surfaceList();
        bead = owner.beadList();
        node = owner.beadNode();
        if (!bead.empty() && node.size() != 3) throw OpenMMException("WallForce: bead particles but no bead node");
        for (const vector<int>* v : {&surface, &bead, &node})
            for (int p : *v)
                if (p < 0 || p >= np) throw OpenMMException("WallForce: a wall refers to a missing particle");
        z0 = owner.getSurfaceZ();
        ks = owner.getSurfaceK();
        kb = owner.getBeadK();
    }
    double computeForce(ContextImpl& context, const vector<Vec3>& positions, vector<Vec3>& forces) {
        // Only z components are non-zero; CustomCPPForceImpl adds forces (all of them) to the platform's.
        std::fill(forces.begin(), forces.end(), Vec3());
        double es = 0.0, eb = 0.0;
        for (int p : surface) {
            const double d = positions[p][2] - z0;
            if (d < 0) {
                es += 0.5 * ks * d * d;
                forces[p][2] -= ks * d;
            }
        }
        if (!bead.empty()) {
            const double zc = (positions[node[0]][2] + positions[node[1]][2] + positions[node[2]][2]) / 3.0;
            double fc = 0.0;
            for (int p : bead) {
                const double d = positions[p][2] - zc;
                if (d > 0) {
                    eb += 0.5 * kb * d * d;
                    forces[p][2] -= kb * d;
                    fc += kb * d;
                }
            }
            for (int i = 0; i < 3; i++) forces[node[i]][2] += fc / 3.0;
        }
        owner.lastSurface = es;
        owner.lastBead = eb;
        return es + eb;
    }
private:
    const WallForce& owner;
    vector<int> surface, bead, node;
    double z0 = 0, ks = 0, kb = 0;
};

ForceImpl* WallForce::createImpl() const { return new WallForceImpl(*this); }

} // namespace dnarod
