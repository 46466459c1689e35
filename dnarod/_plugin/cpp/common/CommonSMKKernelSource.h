#ifndef DNAROD_COMMONSMKKERNELSOURCE_H_
#define DNAROD_COMMONSMKKERNELSOURCE_H_
// Device code of the SMK force, written once in the subset of C shared by OpenCL and CUDA that OpenMM's
// Common compute layer defines (real, real3, make_real3, GLOBAL). It is a snippet for OpenMM's
// BondedUtilities: one interaction per rod step with six particles (atom1..3 the left node's triangle,
// atom4..6 the right node's), positions pos1..pos6 (real4), and it must set force1..force6 (real3) and add
// to energy (it runs inside BondedUtilities' loop body, so force1..force6 stay in scope). PARAMS (real, 48 per
// step: K row-major 36, xi0 6, then for the left and the right node 1/(3 l), 1/(sqrt(3) l), 1/l^2; precomputed on
// the host so that no reduced-accuracy native functions enter single precision), FLAGS (int, 1 if
// the right node is the closure image) and GLOBALS (real: Q row-major 9, t 3, ds, 1/ds, Cayley limit) are
// replaced by the argument names BondedUtilities assigns.
// The arithmetic is that of dnarod.core.kernels.step_loads (docs/formulation.md §4; host version SMKForce.cpp stepLoads):
// R = La^T Lb, Omega = (2/ds) axial(R - R^T)/(1 + tr R), Gamma = La^T (cb - ca)/ds,
// E = ds/2 d^T K d with d = (Omega, Gamma) - xi0, left-node loads F = La P, tau = La (M + w x M/2 + w (w.M)/4)
// + e x F, right-node loads -F, -La(...) (mapped back by Q^T for a closure image), and each node's loads
// spread over its particles as F/3 + a x x_i, a = A^-1 tau (A the triangle's second-moment tensor).
namespace dnarod {

static const char* const commonSMKSource = R"DNAROD(
    const GLOBAL real* sp = PARAMS + index*48;
    const int image = FLAGS[index];
    // Node poses from the triangles: c = mean, d1 = (2 p0 - p1 - p2)/(3 l), d2 = (p1 - p2)/(sqrt(3) l),
    // d3 = d1 x d2; frames row-major with the directors as columns.
    real ca[3], cb[3], La[9], Lb[9];
    {
        const real u = sp[42], v = sp[43];
        ca[0] = (pos1.x+pos2.x+pos3.x)/3; ca[1] = (pos1.y+pos2.y+pos3.y)/3; ca[2] = (pos1.z+pos2.z+pos3.z)/3;
        La[0] = (2*pos1.x-pos2.x-pos3.x)*u; La[3] = (2*pos1.y-pos2.y-pos3.y)*u; La[6] = (2*pos1.z-pos2.z-pos3.z)*u;
        La[1] = (pos2.x-pos3.x)*v; La[4] = (pos2.y-pos3.y)*v; La[7] = (pos2.z-pos3.z)*v;
        La[2] = La[3]*La[7]-La[6]*La[4]; La[5] = La[6]*La[1]-La[0]*La[7]; La[8] = La[0]*La[4]-La[3]*La[1];
    }
    {
        const real u = sp[45], v = sp[46];
        cb[0] = (pos4.x+pos5.x+pos6.x)/3; cb[1] = (pos4.y+pos5.y+pos6.y)/3; cb[2] = (pos4.z+pos5.z+pos6.z)/3;
        Lb[0] = (2*pos4.x-pos5.x-pos6.x)*u; Lb[3] = (2*pos4.y-pos5.y-pos6.y)*u; Lb[6] = (2*pos4.z-pos5.z-pos6.z)*u;
        Lb[1] = (pos5.x-pos6.x)*v; Lb[4] = (pos5.y-pos6.y)*v; Lb[7] = (pos5.z-pos6.z)*v;
        Lb[2] = Lb[3]*Lb[7]-Lb[6]*Lb[4]; Lb[5] = Lb[6]*Lb[1]-Lb[0]*Lb[7]; Lb[8] = Lb[0]*Lb[4]-Lb[3]*Lb[1];
    }
    // The right node seen through the screw closure (image = (Q L, Q c + t)).
    real cm[3], Lm[9];
    for (int r = 0; r < 3; r++) {
        if (image) {
            const real q0 = GLOBALS[3*r], q1 = GLOBALS[3*r+1], q2 = GLOBALS[3*r+2];
            cm[r] = GLOBALS[9+r] + q0*cb[0] + q1*cb[1] + q2*cb[2];
            for (int c = 0; c < 3; c++)
                Lm[3*r+c] = q0*Lb[c] + q1*Lb[3+c] + q2*Lb[6+c];
        }
        else {
            cm[r] = cb[r];
            for (int c = 0; c < 3; c++)
                Lm[3*r+c] = Lb[3*r+c];
        }
    }
    real R[9];
    for (int a = 0; a < 3; a++)
        for (int b = 0; b < 3; b++)
            R[3*a+b] = La[a]*Lm[b] + La[3+a]*Lm[3+b] + La[6+a]*Lm[6+b];
    const real den = 1 + R[0] + R[4] + R[8];
    const real ds = GLOBALS[12], inv = GLOBALS[13];
    real Fa[3] = {0, 0, 0}, ta[3] = {0, 0, 0}, Fb[3] = {0, 0, 0}, tb[3] = {0, 0, 0};
    if (!(den > GLOBALS[14])) {
        // at or beyond the Cayley limit: no loads, NaN energy (as the host code)
        const real zero = 0;
        energy += zero/zero;
    }
    else {
        const real iden = 2/den;
        const real w0 = (R[7]-R[5])*iden, w1 = (R[2]-R[6])*iden, w2 = (R[3]-R[1])*iden;
        const real e0 = cm[0]-ca[0], e1 = cm[1]-ca[1], e2 = cm[2]-ca[2];
        real d[6];
        d[0] = w0*inv - sp[36];
        d[1] = w1*inv - sp[37];
        d[2] = w2*inv - sp[38];
        d[3] = (La[0]*e0 + La[3]*e1 + La[6]*e2)*inv - sp[39];
        d[4] = (La[1]*e0 + La[4]*e1 + La[7]*e2)*inv - sp[40];
        d[5] = (La[2]*e0 + La[5]*e1 + La[8]*e2)*inv - sp[41];
        real sig[6];
        real H = 0;
        for (int i = 0; i < 6; i++) {
            real s = 0;
            for (int j = 0; j < 6; j++)
                s += sp[6*i+j]*d[j];
            sig[i] = s;
            H += d[i]*s;
        }
        energy += ((real) 0.5)*ds*H;
        const real M0 = sig[0], M1 = sig[1], M2 = sig[2], P0 = sig[3], P1 = sig[4], P2 = sig[5];
        const real wM = w0*M0 + w1*M1 + w2*M2;
        const real bm0 = M0 + ((real) 0.5)*(w1*M2-w2*M1) + ((real) 0.25)*w0*wM;
        const real bm1 = M1 + ((real) 0.5)*(w2*M0-w0*M2) + ((real) 0.25)*w1*wM;
        const real bm2 = M2 + ((real) 0.5)*(w0*M1-w1*M0) + ((real) 0.25)*w2*wM;
        const real n0 = La[0]*P0 + La[1]*P1 + La[2]*P2;
        const real n1 = La[3]*P0 + La[4]*P1 + La[5]*P2;
        const real n2 = La[6]*P0 + La[7]*P1 + La[8]*P2;
        const real m0 = La[0]*bm0 + La[1]*bm1 + La[2]*bm2;
        const real m1 = La[3]*bm0 + La[4]*bm1 + La[5]*bm2;
        const real m2 = La[6]*bm0 + La[7]*bm1 + La[8]*bm2;
        Fa[0] = n0; Fa[1] = n1; Fa[2] = n2;
        ta[0] = m0 + e1*n2 - e2*n1;
        ta[1] = m1 + e2*n0 - e0*n2;
        ta[2] = m2 + e0*n1 - e1*n0;
        if (image) {  // loads on the image act on the node through Q^T
            for (int a = 0; a < 3; a++) {
                Fb[a] = -(GLOBALS[a]*n0 + GLOBALS[3+a]*n1 + GLOBALS[6+a]*n2);
                tb[a] = -(GLOBALS[a]*m0 + GLOBALS[3+a]*m1 + GLOBALS[6+a]*m2);
            }
        }
        else {
            Fb[0] = -n0; Fb[1] = -n1; Fb[2] = -n2;
            tb[0] = -m0; tb[1] = -m1; tb[2] = -m2;
        }
    }
    // Spread each node's loads over its particles: f_i = F/3 + a x (p_i - c), a = L diag(2/3, 2/3, 1/3) L^T tau / l^2.
    real aa[3], ab[3];
    {
        const real il2 = sp[44];
        const real b0 = (La[0]*ta[0] + La[3]*ta[1] + La[6]*ta[2])*il2*(2/(real) 3);
        const real b1 = (La[1]*ta[0] + La[4]*ta[1] + La[7]*ta[2])*il2*(2/(real) 3);
        const real b2 = (La[2]*ta[0] + La[5]*ta[1] + La[8]*ta[2])*il2/3;
        for (int r = 0; r < 3; r++)
            aa[r] = La[3*r]*b0 + La[3*r+1]*b1 + La[3*r+2]*b2;
    }
    {
        const real il2 = sp[47];
        const real b0 = (Lb[0]*tb[0] + Lb[3]*tb[1] + Lb[6]*tb[2])*il2*(2/(real) 3);
        const real b1 = (Lb[1]*tb[0] + Lb[4]*tb[1] + Lb[7]*tb[2])*il2*(2/(real) 3);
        const real b2 = (Lb[2]*tb[0] + Lb[5]*tb[1] + Lb[8]*tb[2])*il2/3;
        for (int r = 0; r < 3; r++)
            ab[r] = Lb[3*r]*b0 + Lb[3*r+1]*b1 + Lb[3*r+2]*b2;
    }
    real3 x;
    x = make_real3(pos1.x-ca[0], pos1.y-ca[1], pos1.z-ca[2]);
    real3 force1 = make_real3(Fa[0]/3 + aa[1]*x.z - aa[2]*x.y, Fa[1]/3 + aa[2]*x.x - aa[0]*x.z, Fa[2]/3 + aa[0]*x.y - aa[1]*x.x);
    x = make_real3(pos2.x-ca[0], pos2.y-ca[1], pos2.z-ca[2]);
    real3 force2 = make_real3(Fa[0]/3 + aa[1]*x.z - aa[2]*x.y, Fa[1]/3 + aa[2]*x.x - aa[0]*x.z, Fa[2]/3 + aa[0]*x.y - aa[1]*x.x);
    x = make_real3(pos3.x-ca[0], pos3.y-ca[1], pos3.z-ca[2]);
    real3 force3 = make_real3(Fa[0]/3 + aa[1]*x.z - aa[2]*x.y, Fa[1]/3 + aa[2]*x.x - aa[0]*x.z, Fa[2]/3 + aa[0]*x.y - aa[1]*x.x);
    x = make_real3(pos4.x-cb[0], pos4.y-cb[1], pos4.z-cb[2]);
    real3 force4 = make_real3(Fb[0]/3 + ab[1]*x.z - ab[2]*x.y, Fb[1]/3 + ab[2]*x.x - ab[0]*x.z, Fb[2]/3 + ab[0]*x.y - ab[1]*x.x);
    x = make_real3(pos5.x-cb[0], pos5.y-cb[1], pos5.z-cb[2]);
    real3 force5 = make_real3(Fb[0]/3 + ab[1]*x.z - ab[2]*x.y, Fb[1]/3 + ab[2]*x.x - ab[0]*x.z, Fb[2]/3 + ab[0]*x.y - ab[1]*x.x);
    x = make_real3(pos6.x-cb[0], pos6.y-cb[1], pos6.z-cb[2]);
    real3 force6 = make_real3(Fb[0]/3 + ab[1]*x.z - ab[2]*x.y, Fb[1]/3 + ab[2]*x.x - ab[0]*x.z, Fb[2]/3 + ab[0]*x.y - ab[1]*x.x);
)DNAROD";

} // namespace dnarod

#endif
