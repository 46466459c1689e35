// XML serialization of the plugin's forces (so that a System holding them can be copied, pickled and saved with
// OpenMM's XmlSerializer like any other); registered when the Python module is imported.
#include "NodePairForce.h"
#include "SMKForce.h"
#include "WallForce.h"
#include "openmm/serialization/SerializationNode.h"
#include "openmm/serialization/SerializationProxy.h"
#include <string>
#include <typeinfo>

using namespace OpenMM;
using namespace std;

namespace dnarod {

static void baseProperties(const Force& f, SerializationNode& node) {
    node.setIntProperty("version", 1);
    node.setIntProperty("forceGroup", f.getForceGroup());
    node.setStringProperty("name", f.getName());
}

static void setBase(Force& f, const SerializationNode& node) {
    if (node.getIntProperty("version") != 1) throw OpenMMException("unsupported version of a dnarod force");
    f.setForceGroup(node.getIntProperty("forceGroup", 0));
    f.setName(node.getStringProperty("name", f.getName()));
}

class SMKForceProxy : public SerializationProxy {
public:
    SMKForceProxy() : SerializationProxy("dnarod::SMKForce") {}
    void serialize(const void* object, SerializationNode& node) const {
        const SMKForce& f = *reinterpret_cast<const SMKForce*>(object);
        baseProperties(f, node);
        node.setDoubleProperty("ds", f.getDs());
        vector<double> Q = f.getClosureQ(), t = f.getClosureT();
        SerializationNode& cl = node.createChildNode("Closure");
        for (int i = 0; i < 9; i++) cl.setDoubleProperty("Q" + to_string(i), Q[i]);
        for (int i = 0; i < 3; i++) cl.setDoubleProperty("t" + to_string(i), t[i]);
        SerializationNode& nodes = node.createChildNode("Nodes");
        for (const auto& nd : f.nodeList())
            nodes.createChildNode("Node").setIntProperty("p0", nd.p[0]).setIntProperty("p1", nd.p[1])
                .setIntProperty("p2", nd.p[2]).setDoubleProperty("r", nd.radius);
        SerializationNode& steps = node.createChildNode("Steps");
        for (const auto& s : f.stepList()) {
            SerializationNode& c = steps.createChildNode("Step");
            c.setIntProperty("left", s.left).setIntProperty("right", s.right).setIntProperty("image", s.image ? 1 : 0);
            for (int i = 0; i < 36; i++) c.setDoubleProperty("K" + to_string(i), s.K[i]);
            for (int i = 0; i < 6; i++) c.setDoubleProperty("x" + to_string(i), s.xi0[i]);
        }
    }
    void* deserialize(const SerializationNode& node) const {
        SMKForce* f = new SMKForce();
        try {
            setBase(*f, node);
            f->setDs(node.getDoubleProperty("ds"));
            const SerializationNode& cl = node.getChildNode("Closure");
            vector<double> Q(9), t(3);
            for (int i = 0; i < 9; i++) Q[i] = cl.getDoubleProperty("Q" + to_string(i));
            for (int i = 0; i < 3; i++) t[i] = cl.getDoubleProperty("t" + to_string(i));
            f->setClosure(Q, t);
            for (const auto& c : node.getChildNode("Nodes").getChildren())
                f->addNode(c.getIntProperty("p0"), c.getIntProperty("p1"), c.getIntProperty("p2"), c.getDoubleProperty("r"));
            for (const auto& c : node.getChildNode("Steps").getChildren()) {
                vector<double> K(36), x(6);
                for (int i = 0; i < 36; i++) K[i] = c.getDoubleProperty("K" + to_string(i));
                for (int i = 0; i < 6; i++) x[i] = c.getDoubleProperty("x" + to_string(i));
                f->addStep(c.getIntProperty("left"), c.getIntProperty("right"), K, x, c.getIntProperty("image") != 0);
            }
        } catch (...) {
            delete f;
            throw;
        }
        return f;
    }
};

class NodePairForceProxy : public SerializationProxy {
public:
    NodePairForceProxy() : SerializationProxy("dnarod::NodePairForce") {}
    void serialize(const void* object, SerializationNode& node) const {
        const NodePairForce& f = *reinterpret_cast<const NodePairForce*>(object);
        baseProperties(f, node);
        const NodePairForce::Params& p = f.params();
        node.setDoubleProperty("eps", p.eps).setDoubleProperty("sigma", p.sigma).setDoubleProperty("rcWca", p.rcWca)
            .setDoubleProperty("aDh", p.aDh).setDoubleProperty("kappa", p.kappa).setDoubleProperty("rcDh", p.rcDh)
            .setIntProperty("nExclude", p.nExclude).setIntProperty("circular", p.circular ? 1 : 0);
        SerializationNode& nodes = node.createChildNode("Nodes");
        const vector<int>& q = f.particleList();
        for (size_t k = 0; k + 2 < q.size(); k += 3)
            nodes.createChildNode("Node").setIntProperty("p0", q[k]).setIntProperty("p1", q[k + 1]).setIntProperty("p2", q[k + 2]);
    }
    void* deserialize(const SerializationNode& node) const {
        NodePairForce* f = new NodePairForce();
        try {
            setBase(*f, node);
            f->setParameters(node.getDoubleProperty("eps"), node.getDoubleProperty("sigma"), node.getDoubleProperty("rcWca"),
                             node.getDoubleProperty("aDh"), node.getDoubleProperty("kappa"), node.getDoubleProperty("rcDh"),
                             node.getIntProperty("nExclude"), node.getIntProperty("circular") != 0);
            for (const auto& c : node.getChildNode("Nodes").getChildren())
                f->addNode(c.getIntProperty("p0"), c.getIntProperty("p1"), c.getIntProperty("p2"));
        } catch (...) {
            delete f;
            throw;
        }
        return f;
    }
};

class WallForceProxy : public SerializationProxy {
public:
    WallForceProxy() : SerializationProxy("dnarod::WallForce") {}
    void serialize(const void* object, SerializationNode& node) const {
        const WallForce& f = *reinterpret_cast<const WallForce*>(object);
        baseProperties(f, node);
        node.setDoubleProperty("zSurface", f.getSurfaceZ()).setDoubleProperty("kSurface", f.getSurfaceK())
            .setDoubleProperty("kBead", f.getBeadK());
        const vector<int>& b = f.beadNode();
        if (b.size() == 3)
            node.createChildNode("BeadNode").setIntProperty("p0", b[0]).setIntProperty("p1", b[1]).setIntProperty("p2", b[2]);
        SerializationNode& s = node.createChildNode("Surface");
        for (int p : f.surfaceList()) s.createChildNode("Particle").setIntProperty("p", p);
        SerializationNode& bd = node.createChildNode("Bead");
        for (int p : f.beadList()) bd.createChildNode("Particle").setIntProperty("p", p);
    }
    void* deserialize(const SerializationNode& node) const {
        WallForce* f = new WallForce();
        try {
            setBase(*f, node);
            f->setParameters(node.getDoubleProperty("zSurface"), node.getDoubleProperty("kSurface"),
                             node.getDoubleProperty("kBead"));
            for (const auto& c : node.getChildren())
                if (c.getName() == "BeadNode") f->setBeadNode(c.getIntProperty("p0"), c.getIntProperty("p1"), c.getIntProperty("p2"));
            for (const auto& c : node.getChildNode("Surface").getChildren()) f->addSurfaceParticle(c.getIntProperty("p"));
            for (const auto& c : node.getChildNode("Bead").getChildren()) f->addBeadParticle(c.getIntProperty("p"));
        } catch (...) {
            delete f;
            throw;
        }
        return f;
    }
};

void registerSerializationProxies() {
    static bool done = false;
    if (done) return;
    done = true;
    SerializationProxy::registerProxy(typeid(SMKForce), new SMKForceProxy());
    SerializationProxy::registerProxy(typeid(NodePairForce), new NodePairForceProxy());
    SerializationProxy::registerProxy(typeid(WallForce), new WallForceProxy());
}

} // namespace dnarod
