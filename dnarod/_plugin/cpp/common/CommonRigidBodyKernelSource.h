#ifndef DNAROD_COMMONRIGIDBODYKERNELSOURCE_H_
#define DNAROD_COMMONRIGIDBODYKERNELSOURCE_H_
// Device code of one RigidBodyIntegrator step (one work item per node), written once for OpenCL and CUDA in
// OpenMM's Common compute dialect (mixed, mixed4, real4, mm_long, KERNEL, GLOBAL, GLOBAL_ID, GLOBAL_SIZE,
// USE_MIXED_PRECISION). The same arithmetic as the host code (RigidBodyIntegrator.cpp run()): node state from
// the triangle (Gram-Schmidt frame), node force and torque from the particle forces (64-bit fixed point),
// kick, drift, exact free-rotor sub-flows R1(h/2) R2(h/2) R3(h) R2(h/2) R1(h/2), the O step on the lab momentum
// and the body angular momentum, and the rigid triangle written back.
namespace dnarod {

static const char* const commonRigidBodySource = R"DNAROD(
// sin and cos: Taylor polynomials for |x| < 0.8 (truncation < 1e-19, as the host code; rotor angles per
// sub-step are ~0.05 rad at the default step), the library functions beyond.
DEVICE void dnarodSinCos(mixed x, mixed* s, mixed* c) {
    if (fabs(x) < (mixed) 0.8f) {
        const mixed x2 = x*x;
        *s = x*(1 + x2*(-1/(mixed) 6 + x2*(1/(mixed) 120 + x2*(-1/(mixed) 5040 + x2*(1/(mixed) 362880 + x2*(
                -1/(mixed) 39916800 + x2*(1/(mixed) 6227020800L + x2*(-1/(mixed) 1307674368000L + x2*(
                1/(mixed) 355687428096000L)))))))));
        *c = 1 + x2*(-1/(mixed) 2 + x2*(1/(mixed) 24 + x2*(-1/(mixed) 720 + x2*(1/(mixed) 40320 + x2*(
                -1/(mixed) 3628800 + x2*(1/(mixed) 479001600 + x2*(-1/(mixed) 87178291200L + x2*(
                1/(mixed) 20922789888000L + x2*(-1/(mixed) 6402373705728000L)))))))));
    }
    else {
        *s = sin(x);
        *c = cos(x);
    }
}

// rotate frame columns b, d and body momenta pi_b, pi_d by angle scale * pi_a / J_a about body axis a
DEVICE void dnarodSubFlow(mixed* L, mixed* pi, const mixed* iJ, int a, int b, int d, mixed scale) {
    const mixed x = scale*pi[a]*iJ[a];
    mixed s, co;
    dnarodSinCos(x, &s, &co);
    for (int r = 0; r < 3; r++) {
        const mixed xb = L[3*r+b], xd = L[3*r+d];
        L[3*r+b] = co*xb + s*xd;
        L[3*r+d] = co*xd - s*xb;
    }
    const mixed qb = pi[b], qd = pi[d];
    pi[b] = co*qb + s*qd;
    pi[d] = co*qd - s*qb;
}

DEVICE void dnarodRotor(mixed* L, mixed* pi, const mixed* iJ, mixed h) {
    const mixed hh = h/2;
    dnarodSubFlow(L, pi, iJ, 0, 1, 2, hh);
    dnarodSubFlow(L, pi, iJ, 1, 2, 0, hh);
    dnarodSubFlow(L, pi, iJ, 2, 0, 1, h);
    dnarodSubFlow(L, pi, iJ, 1, 2, 0, hh);
    dnarodSubFlow(L, pi, iJ, 0, 1, 2, hh);
}

KERNEL void dnarodRigidBodyStep(int numNodes, GLOBAL real4* RESTRICT posq, GLOBAL real4* RESTRICT posqCorrection,
        GLOBAL mixed4* RESTRICT velm, GLOBAL const mm_long* RESTRICT force, GLOBAL const int4* RESTRICT nodeAtoms,
        GLOBAL const mixed4* RESTRICT nodeParams, GLOBAL const float4* RESTRICT random, unsigned int randomIndex,
        mixed dt, mixed cfric, mixed noise, int langevin) {
    const mixed fscale = 1/(mixed) 0x100000000;
    for (int k = GLOBAL_ID; k < numNodes; k += GLOBAL_SIZE) {
        const mixed4 prm = nodeParams[k];  // m, l, 1/m, 1/J1 (= 1/J2 = 2/(m l^2))
        if (prm.x == 0)
            continue;  // clamped node: nothing moves
        const int4 at = nodeAtoms[k];
        const int atom[3] = {at.x, at.y, at.z};
        mixed p[3][3], u[3][3], f[3][3];
        real w[3];
        for (int i = 0; i < 3; i++) {
            const real4 pq = posq[atom[i]];
            w[i] = pq.w;
#ifdef USE_MIXED_PRECISION
            const real4 pc = posqCorrection[atom[i]];
            p[i][0] = pq.x + (mixed) pc.x; p[i][1] = pq.y + (mixed) pc.y; p[i][2] = pq.z + (mixed) pc.z;
#else
            p[i][0] = pq.x; p[i][1] = pq.y; p[i][2] = pq.z;
#endif
            const mixed4 v = velm[atom[i]];
            u[i][0] = v.x; u[i][1] = v.y; u[i][2] = v.z;
            f[i][0] = fscale*force[atom[i]];
            f[i][1] = fscale*force[atom[i]+PADDED_NUM_ATOMS];
            f[i][2] = fscale*force[atom[i]+2*PADDED_NUM_ATOMS];
        }
        mixed c[3], d1[3], d2[3], L[9];
        for (int r = 0; r < 3; r++) {
            c[r] = (p[0][r] + p[1][r] + p[2][r])/3;
            d1[r] = 2*p[0][r] - p[1][r] - p[2][r];
            d2[r] = p[1][r] - p[2][r];
        }
        mixed nn = 1/sqrt(d1[0]*d1[0] + d1[1]*d1[1] + d1[2]*d1[2]);
        for (int r = 0; r < 3; r++)
            d1[r] *= nn;
        const mixed dd = d1[0]*d2[0] + d1[1]*d2[1] + d1[2]*d2[2];
        for (int r = 0; r < 3; r++)
            d2[r] -= dd*d1[r];
        nn = 1/sqrt(d2[0]*d2[0] + d2[1]*d2[1] + d2[2]*d2[2]);
        for (int r = 0; r < 3; r++) {
            d2[r] *= nn;
            L[3*r] = d1[r];
            L[3*r+1] = d2[r];
        }
        L[2] = d1[1]*d2[2] - d1[2]*d2[1];
        L[5] = d1[2]*d2[0] - d1[0]*d2[2];
        L[8] = d1[0]*d2[1] - d1[1]*d2[0];
        // node velocity, force, torque and sum x_i x (u_i - v)
        mixed v[3], F[3], tau[3] = {0, 0, 0}, h[3] = {0, 0, 0};
        for (int r = 0; r < 3; r++) {
            v[r] = (u[0][r] + u[1][r] + u[2][r])/3;
            F[r] = f[0][r] + f[1][r] + f[2][r];
        }
        for (int i = 0; i < 3; i++) {
            const mixed x0 = p[i][0]-c[0], x1 = p[i][1]-c[1], x2 = p[i][2]-c[2];
            const mixed u0 = u[i][0]-v[0], u1 = u[i][1]-v[1], u2 = u[i][2]-v[2];
            h[0] += x1*u2 - x2*u1;
            h[1] += x2*u0 - x0*u2;
            h[2] += x0*u1 - x1*u0;
            tau[0] += x1*f[i][2] - x2*f[i][1];
            tau[1] += x2*f[i][0] - x0*f[i][2];
            tau[2] += x0*f[i][1] - x1*f[i][0];
        }
        const mixed m = prm.x, l = prm.y, im = prm.z;
        const mixed iJ[3] = {prm.w, prm.w, prm.w/2};
        // V: kick of the lab momentum and the body angular momentum pi = J omega_body = m/3 L^T h
        mixed P[3], pi[3];
        for (int a = 0; a < 3; a++) {
            P[a] = m*v[a] + dt*F[a];
            pi[a] = (m/3)*(L[a]*h[0] + L[3+a]*h[1] + L[6+a]*h[2]) + dt*(L[a]*tau[0] + L[3+a]*tau[1] + L[6+a]*tau[2]);
        }
        if (!langevin) {
            for (int a = 0; a < 3; a++)
                c[a] += dt*P[a]*im;
            dnarodRotor(L, pi, iJ, dt);
        }
        else {
            const mixed hdt = dt/2;
            for (int a = 0; a < 3; a++)
                c[a] += hdt*P[a]*im;
            dnarodRotor(L, pi, iJ, hdt);
            const float4 r1 = random[randomIndex+2*k], r2 = random[randomIndex+2*k+1];
            const mixed sP = noise*sqrt(m), sPi12 = noise*sqrt(m*l*l/2), sPi3 = noise*sqrt(m*l*l);
            P[0] = cfric*P[0] + sP*r1.x;
            P[1] = cfric*P[1] + sP*r1.y;
            P[2] = cfric*P[2] + sP*r1.z;
            pi[0] = cfric*pi[0] + sPi12*r1.w;
            pi[1] = cfric*pi[1] + sPi12*r2.x;
            pi[2] = cfric*pi[2] + sPi3*r2.y;
            for (int a = 0; a < 3; a++)
                c[a] += hdt*P[a]*im;
            dnarodRotor(L, pi, iJ, hdt);
        }
        // the rigid triangle: p_i = c + l L b_i, u_i = v + (L omega) x (p_i - c)
        mixed om[3];
        for (int a = 0; a < 3; a++)
            om[a] = pi[a]*iJ[a];
        const mixed wl0 = L[0]*om[0] + L[1]*om[1] + L[2]*om[2];
        const mixed wl1 = L[3]*om[0] + L[4]*om[1] + L[5]*om[2];
        const mixed wl2 = L[6]*om[0] + L[7]*om[1] + L[8]*om[2];
        const mixed v0 = P[0]*im, v1 = P[1]*im, v2 = P[2]*im;
        const mixed s32 = sqrt((mixed) 3)/2;
        const mixed ox[3] = {1, -1/(mixed) 2, -1/(mixed) 2}, oy[3] = {0, s32, -s32};
        for (int i = 0; i < 3; i++) {
            const mixed x0 = l*(L[0]*ox[i] + L[1]*oy[i]);
            const mixed x1 = l*(L[3]*ox[i] + L[4]*oy[i]);
            const mixed x2 = l*(L[6]*ox[i] + L[7]*oy[i]);
            const mixed q0 = c[0]+x0, q1 = c[1]+x1, q2 = c[2]+x2;
            posq[atom[i]] = make_real4((real) q0, (real) q1, (real) q2, w[i]);
#ifdef USE_MIXED_PRECISION
            posqCorrection[atom[i]] = make_real4((real) (q0-(real) q0), (real) (q1-(real) q1), (real) (q2-(real) q2), 0);
#endif
            const mixed4 vo = velm[atom[i]];
            velm[atom[i]] = make_mixed4(v0 + wl1*x2 - wl2*x1, v1 + wl2*x0 - wl0*x2, v2 + wl0*x1 - wl1*x0, vo.w);
        }
    }
}
)DNAROD";

} // namespace dnarod

#endif
