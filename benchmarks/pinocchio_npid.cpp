// Benchmark driver (not product code): the NPID law of the default arm
// (glasgow_2link) evaluated with Pinocchio, for benchmarks/codegen.py.
//
//   u = B^-1 (J C^-1 (K1 e + K2 e' + yd'') + G) + B^-1 W C^-1 (e' + K2 e + K1 int e)
//
// with C = I, G = nonlinear effects + diag(Kt Kv / R) theta', B = diag(Kt / R).
// Two variants: "crba" (J by crba, h by nonLinearEffects, J a + h by hand) and
// "rnea" (rnea(q, v, a) = J a + h in one pass). The model is built in code
// (no URDF parser): planar chain, revolute Z joints, values of
// derive/model/arms/glasgow_2link.toml, gravity zero (horizontal arm).
//
// Usage: pinocchio_npid ITERATIONS REPEATS th1 th2 dth1 dth2 yd1 yd2 dyd1 dyd2 ddyd1 ddyd2 ie1 ie2
// Prints "u <u1> <u2>" (both variants at the given state, %.17g) and
// "ns <variant> <best ns per call>" for each variant (best of REPEATS).
#include <cstdio>
#include <cstdlib>
#include <ctime>

#include <pinocchio/multibody.hpp>
#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/algorithm/rnea.hpp>

namespace pin = pinocchio;
typedef Eigen::Vector2d V2;
typedef Eigen::Matrix2d M2;

static const double L = 0.38, M_LINK = 0.361, COM = 0.19;
static const double M_MOTOR2 = 0.44, M_TIP = 0.1;
static const double K1 = 4.8, K2 = 3.0;

struct Law {
    pin::Model model;
    pin::Data *data;
    V2 Binv, damp;
    M2 W;

    Law() {
        model.gravity.setZero();  // horizontal plane
        const double I_rod = M_LINK * L * L / 12.0;
        const Eigen::Matrix3d I_com = Eigen::Vector3d(0.0, I_rod, I_rod).asDiagonal();
        const pin::Inertia link(M_LINK, Eigen::Vector3d(COM, 0, 0), I_com);
        const pin::Inertia motor2(M_MOTOR2, Eigen::Vector3d(L, 0, 0), Eigen::Matrix3d::Zero());
        const pin::Inertia tip(M_TIP, Eigen::Vector3d(L, 0, 0), Eigen::Matrix3d::Zero());
        pin::JointIndex j1 = model.addJoint(0, pin::JointModelRZ(), pin::SE3::Identity(), "joint1");
        model.appendBodyToJoint(j1, link + motor2, pin::SE3::Identity());
        pin::SE3 at_end = pin::SE3::Identity();
        at_end.translation() << L, 0, 0;
        pin::JointIndex j2 = model.addJoint(j1, pin::JointModelRZ(), at_end, "joint2");
        model.appendBodyToJoint(j2, link + tip, pin::SE3::Identity());
        data = new pin::Data(model);
        const double Kt[2] = {0.23, 0.044}, Kv[2] = {0.29, 0.047}, R[2] = {3.4, 5.0};
        for (int i = 0; i < 2; ++i) {
            Binv[i] = R[i] / Kt[i];
            damp[i] = Kt[i] * Kv[i] / R[i];
        }
        W << 1, 0, 1, 2;
    }

    // x = (theta, dtheta, yd, dyd, ddyd, int_e), each 2 entries.
    template <bool RNEA>
    V2 u(const double *x) {
        const V2 q(x[0], x[1]), v(x[2], x[3]), yd(x[4], x[5]), dyd(x[6], x[7]), ddyd(x[8], x[9]),
            ie(x[10], x[11]);
        const V2 e = yd - q, de = dyd - v;  // C = I
        const V2 a = K1 * e + K2 * de + ddyd;
        V2 tau;
        if (RNEA) {
            tau = pin::rnea(model, *data, q, v, a);
        } else {
            pin::crba(model, *data, q);
            data->M.triangularView<Eigen::StrictlyLower>() =
                data->M.transpose().triangularView<Eigen::StrictlyLower>();
            pin::nonLinearEffects(model, *data, q, v);
            tau = data->M * a + data->nle;
        }
        tau += damp.cwiseProduct(v);
        return Binv.cwiseProduct(tau + W * (de + K2 * e + K1 * ie));
    }
};

static double now(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return t.tv_sec + 1e-9 * t.tv_nsec;
}

enum { NS = 16 };
static volatile double sink;

template <bool RNEA>
static double time_law(Law &law, const double xs[NS][12], long iterations, int repeats) {
    double best = 1e300;
    for (int r = 0; r < repeats; ++r) {
        double acc = 0;
        const double t0 = now();
        for (long i = 0; i < iterations; ++i) {
            const V2 u = law.u<RNEA>(xs[i & (NS - 1)]);
            acc += u[0] + u[1];
        }
        const double t = now() - t0;
        sink = acc;
        if (t < best) best = t;
    }
    return best / iterations * 1e9;
}

int main(int argc, char **argv) {
    if (argc != 15) {
        std::fprintf(stderr, "usage: %s ITERATIONS REPEATS x[12]\n", argv[0]);
        return 2;
    }
    const long iterations = std::atol(argv[1]);
    const int repeats = std::atoi(argv[2]);
    double x0[12];
    for (int k = 0; k < 12; ++k) x0[k] = std::atof(argv[3 + k]);
    Law law;
    const V2 uc = law.u<false>(x0), ur = law.u<true>(x0);
    std::printf("u_crba %.17g %.17g\nu_rnea %.17g %.17g\n", uc[0], uc[1], ur[0], ur[1]);
    double xs[NS][12];  // varying states around x0, so nothing is constant
    for (int s = 0; s < NS; ++s)
        for (int k = 0; k < 12; ++k) xs[s][k] = x0[k] * (1.0 + 0.03 * s) + 0.01 * ((s * 7 + k * 3) % 11 - 5);
    std::printf("ns crba %.3f\n", time_law<false>(law, xs, iterations, repeats));
    std::printf("ns rnea %.3f\n", time_law<true>(law, xs, iterations, repeats));
    return 0;
}
