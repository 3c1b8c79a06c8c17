// Benchmark driver (not product code): Pinocchio's rnea(q, v, a) of a URDF arm, for
// benchmarks/spatial.py. The model is the one Python's pin.buildModelFromUrdf reads (the
// arm file's off-chain joints locked at 0 by pin.buildReducedModel), saved with
// written as text by benchmarks/spatial.py (the pip wheels ship neither urdfdom headers for
// the C++ URDF parser nor the serialization headers): one line per joint,
//   parent  R(9, row-major) p(3)  axis(3)  mass  lever(3)  I(6: xx xy xz yy yz zz)
// every joint revolute about its unit axis (RX, RY, RZ when the axis is one of x, y, z).
//
// Usage: pinocchio_rnea_urdf MODEL_TEXT ITERATIONS REPEATS [regressor]
// Prints "nv <n>" and "ns rnea <best ns per call>" (best of REPEATS); with "regressor" also
// "ns regressor <best ns per call>" of computeJointTorqueRegressor(q, v, a) (benchmarks/identify.py).
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <string>
#include <vector>

#include <pinocchio/multibody.hpp>
#include <pinocchio/algorithm/rnea.hpp>
#include <pinocchio/algorithm/regressor.hpp>
#include <pinocchio/algorithm/joint-configuration.hpp>

namespace pin = pinocchio;

static double now() {
    timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

int main(int argc, char **argv) {
    if (argc != 4 && argc != 5) {
        std::fprintf(stderr, "usage: %s MODEL_TEXT ITERATIONS REPEATS [regressor]\n", argv[0]);
        return 2;
    }
    pin::Model model;
    FILE *f = std::fopen(argv[1], "r");
    if (!f) return 2;
    int parent;
    while (std::fscanf(f, "%d", &parent) == 1) {
        double x[28];
        for (int k = 0; k < 28; ++k)
            if (std::fscanf(f, "%lf", &x[k]) != 1) return 2;
        Eigen::Matrix3d R;
        R << x[0], x[1], x[2], x[3], x[4], x[5], x[6], x[7], x[8];
        const pin::SE3 placement(R, Eigen::Vector3d(x[9], x[10], x[11]));
        const std::string name = "j" + std::to_string(model.njoints);
        const Eigen::Vector3d axis(x[12], x[13], x[14]);
        pin::JointIndex j;   // Pinocchio's specialised joints about x, y, z where the axis is one
        if (axis == Eigen::Vector3d::UnitX()) j = model.addJoint(parent, pin::JointModelRX(), placement, name);
        else if (axis == Eigen::Vector3d::UnitY()) j = model.addJoint(parent, pin::JointModelRY(), placement, name);
        else if (axis == Eigen::Vector3d::UnitZ()) j = model.addJoint(parent, pin::JointModelRZ(), placement, name);
        else j = model.addJoint(parent, pin::JointModelRevoluteUnaligned(axis), placement, name);
        Eigen::Matrix3d I;
        I << x[19], x[20], x[21], x[20], x[22], x[23], x[21], x[23], x[24];
        (void)x[25]; (void)x[26]; (void)x[27];
        model.appendBodyToJoint(j, pin::Inertia(x[15], Eigen::Vector3d(x[16], x[17], x[18]), I), pin::SE3::Identity());
    }
    std::fclose(f);
    pin::Data data(model);
    const long iterations = std::atol(argv[2]);
    const int repeats = std::atoi(argv[3]);
    enum { NS = 16 };
    std::vector<Eigen::VectorXd> q(NS), v(NS), a(NS);
    for (int s = 0; s < NS; ++s) {
        q[s] = pin::neutral(model);
        v[s] = Eigen::VectorXd::Zero(model.nv);
        a[s] = Eigen::VectorXd::Zero(model.nv);
        for (int k = 0; k < model.nv; ++k) {
            v[s][k] = 0.1 * ((s * 7 + k * 3) % 11 - 5);
            a[s][k] = 0.2 * ((s * 5 + k * 7) % 13 - 6);
        }
        for (int k = 0; k < model.nq; ++k) q[s][k] += 0.05 * ((s * 3 + k * 5) % 17 - 8);
        pin::normalize(model, q[s]);
    }
    double best = 1e300, acc = 0;
    for (int r = 0; r < repeats; ++r) {
        const double t0 = now();
        for (long i = 0; i < iterations; ++i) {
            const int s = (int)(i & (NS - 1));
            acc += pin::rnea(model, data, q[s], v[s], a[s])[0];
        }
        const double t = now() - t0;
        if (t < best) best = t;
    }
    std::printf("nv %d\nns rnea %.3f\n", (int)model.nv, best / (double)iterations * 1e9);
    if (argc == 5 && std::string(argv[4]) == "regressor") {
        double best_y = 1e300;
        for (int r = 0; r < repeats; ++r) {
            const double t0 = now();
            for (long i = 0; i < iterations; ++i) {
                const int s = (int)(i & (NS - 1));
                acc += pin::computeJointTorqueRegressor(model, data, q[s], v[s], a[s])(0, 0);
            }
            const double t = now() - t0;
            if (t < best_y) best_y = t;
        }
        std::printf("ns regressor %.3f\n", best_y / (double)iterations * 1e9);
    }
    std::printf("sink %g\n", acc);
    return 0;
}
