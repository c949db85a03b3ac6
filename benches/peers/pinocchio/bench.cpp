// Pinocchio on the models and inputs of `dynid bench`, timed the way `dynid bench` times itself.
//
//   bench MODELS    (MODELS: the output of `dynid bench-models`; run.sh does all of this)
//
// Every arm comes from MODELS: the modified D-H table (Craig: joint i's frame is
// RotX(alpha) TransX(a) TransZ(d) RotZ(theta + q) from frame i-1 for a revolute joint,
// ... RotZ(theta) TransZ(d + q) for a prismatic one), gravity, the inertial parameters dynid
// evaluates its kernels with (XX XY XZ YY YZ ZZ MX MY MZ M about link frame i's origin), and the
// 1024-sample input pool with dynid's inverse-dynamics torques. Nothing about an arm is written
// here.
//
// Before timing, on every pool sample: rnea = dynid's torques, M·a + nle = rnea, Y·π = rnea and
// g = rnea(q, 0, 0), each to 1e-9 relative (max |error| / max(1, max |rnea|), dynid's measure).
// A failure is printed and the program exits with status 1 without timing anything.
//
// Timing (dynid's src/bench.rs, `time_per_call`): call i uses pool sample i mod 1024; N calls per
// repetition, N doubled from 1024 until a repetition takes half the target, then scaled to the
// target and rounded up to whole passes over the pool; one warm-up repetition, then `reps` timed
// ones; the median of elapsed / N in ns per call. Target, reps and the initial busy warm-up come
// from the `timing` line of MODELS (dynid's Settings::quick()); PEERS_TARGET_MS / PEERS_REPS
// override them.
//
// Output: `#` comment lines, a human-readable table, and one `pinocchio,<arm>,<algo>,<median_ns>`
// line per measurement (algo: rnea, crba, nle, regressor, gravity, aba, minverse, rnea_derivatives,
// aba_derivatives; dynid's forward-dynamics kernels get the pool's q̈ slot as τ, so Pinocchio's
// `aba` and `computeABADerivatives` do too), which is what
// `dynid bench --pinocchio FILE` reads.

#include <pinocchio/multibody.hpp>
#include <pinocchio/algorithm/aba.hpp>
#include <pinocchio/algorithm/aba-derivatives.hpp>
#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/algorithm/rnea-derivatives.hpp>
#include <pinocchio/algorithm/regressor.hpp>
#include <pinocchio/algorithm/rnea.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <stdexcept>
#include <string>
#include <vector>

#ifndef PEERS_CXX
#define PEERS_CXX "?"
#endif
#ifndef PEERS_FLAGS
#define PEERS_FLAGS "?"
#endif

using Eigen::MatrixXd;
using Eigen::VectorXd;

namespace
{

struct Joint
{
  bool prismatic;
  double alpha, a, d, theta;
};

struct Arm
{
  std::string name;
  int dof = 0;
  Eigen::Vector3d gravity;
  std::vector<Joint> joints;
  std::vector<Eigen::Matrix<double, 10, 1>> inertia; // dynid order, about the link origin
  std::vector<VectorXd> q, v, a, tau;                // the pool; tau: dynid's inverse dynamics
};

struct Timing
{
  double target_s = 0.01;
  int reps = 7;
  double warm_up_s = 0.3;
};

[[noreturn]] void fail(const std::string & msg)
{
  throw std::runtime_error(msg);
}

void expect(std::istream & in, const std::string & word)
{
  std::string got;
  if (!(in >> got) || got != word)
    fail("models file: expected `" + word + "`, found `" + got + "`");
}

template<class T>
T read(std::istream & in, const char * what)
{
  T x;
  if (!(in >> x))
    fail(std::string("models file: cannot read ") + what);
  return x;
}

void readVector(std::istream & in, VectorXd & out, int n)
{
  out.resize(n);
  for (int j = 0; j < n; ++j)
    out[j] = read<double>(in, "a sample value");
}

// The format is documented in src/cli/bench_models.rs.
std::vector<Arm> readModels(const std::string & path, Timing & timing)
{
  std::ifstream in(path);
  if (!in)
    fail("cannot open " + path);
  expect(in, "dynid-bench-models");
  if (read<int>(in, "the format version") != 1)
    fail("models file: unknown format version (rebuild dynid and this harness)");
  expect(in, "timing");
  timing.target_s = read<double>(in, "target_ns") * 1e-9;
  timing.reps = read<int>(in, "reps");
  timing.warm_up_s = read<double>(in, "warm_up_ns") * 1e-9;
  std::vector<Arm> arms;
  std::string tag;
  while (in >> tag)
  {
    if (tag != "arm")
      fail("models file: expected `arm`, found `" + tag + "`");
    Arm arm;
    arm.name = read<std::string>(in, "the arm name");
    arm.dof = read<int>(in, "dof");
    const int pool = read<int>(in, "the pool size");
    if (arm.dof < 1 || pool < 1 || (pool & (pool - 1)) != 0)
      fail("models file: " + arm.name + ": bad dof or pool size (a power of two)");
    expect(in, "gravity");
    for (int j = 0; j < 3; ++j)
      arm.gravity[j] = read<double>(in, "gravity");
    for (int i = 1; i <= arm.dof; ++i)
    {
      expect(in, "joint");
      if (read<int>(in, "the joint number") != i)
        fail("models file: joints out of order");
      const std::string kind = read<std::string>(in, "the joint kind");
      if (kind != "revolute" && kind != "prismatic")
        fail("models file: unknown joint kind " + kind);
      Joint jt{kind == "prismatic", 0, 0, 0, 0};
      jt.alpha = read<double>(in, "alpha");
      jt.a = read<double>(in, "a");
      jt.d = read<double>(in, "d");
      jt.theta = read<double>(in, "theta");
      arm.joints.push_back(jt);
    }
    for (int i = 1; i <= arm.dof; ++i)
    {
      expect(in, "inertia");
      if (read<int>(in, "the link number") != i)
        fail("models file: inertias out of order");
      Eigen::Matrix<double, 10, 1> p;
      for (int j = 0; j < 10; ++j)
        p[j] = read<double>(in, "an inertial parameter");
      arm.inertia.push_back(p);
    }
    arm.q.resize(pool), arm.v.resize(pool), arm.a.resize(pool), arm.tau.resize(pool);
    for (int k = 0; k < pool; ++k)
    {
      expect(in, "sample");
      if (read<int>(in, "the sample number") != k)
        fail("models file: samples out of order");
      readVector(in, arm.q[k], arm.dof);
      readVector(in, arm.v[k], arm.dof);
      readVector(in, arm.a[k], arm.dof);
      readVector(in, arm.tau[k], arm.dof);
    }
    expect(in, "end");
    expect(in, arm.name);
    arms.push_back(std::move(arm));
  }
  if (arms.empty())
    fail("models file: no arm");
  return arms;
}

pinocchio::Model buildModel(const Arm & arm)
{
  using pinocchio::SE3;
  pinocchio::Model model;
  model.name = arm.name;
  model.gravity.linear(arm.gravity);
  pinocchio::JointIndex parent = 0;
  for (int i = 0; i < arm.dof; ++i)
  {
    const Joint & j = arm.joints[i];
    // Frame i at q = 0 in frame i-1; the joint then rotates about / slides along its z axis.
    // RotZ(theta) and TransZ(d) commute, so one placement serves both kinds.
    const SE3 rotX(Eigen::AngleAxisd(j.alpha, Eigen::Vector3d::UnitX()).toRotationMatrix(),
                   Eigen::Vector3d::Zero());
    const SE3 transX(Eigen::Matrix3d::Identity(), Eigen::Vector3d(j.a, 0, 0));
    const SE3 transZ(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0, 0, j.d));
    const SE3 rotZ(Eigen::AngleAxisd(j.theta, Eigen::Vector3d::UnitZ()).toRotationMatrix(),
                   Eigen::Vector3d::Zero());
    const SE3 placement = rotX * transX * transZ * rotZ;
    const std::string name = "joint" + std::to_string(i + 1);
    const pinocchio::JointIndex id =
      j.prismatic ? model.addJoint(parent, pinocchio::JointModelPZ(), placement, name)
                  : model.addJoint(parent, pinocchio::JointModelRZ(), placement, name);
    // dynid: XX XY XZ YY YZ ZZ MX MY MZ M about the link origin.
    // Pinocchio's dynamic parameters: m, mc_x, mc_y, mc_z, Ixx, Ixy, Iyy, Ixz, Iyz, Izz (same point).
    const auto & p = arm.inertia[i];
    Eigen::Matrix<double, 10, 1> pin;
    pin << p[9], p[6], p[7], p[8], p[0], p[1], p[3], p[2], p[4], p[5];
    model.appendBodyToJoint(id, pinocchio::Inertia::FromDynamicParameters(pin), SE3::Identity());
    parent = id;
  }
  return model;
}

// dynid's error measure: max |got − want| / max(1, max |want|).
double relErr(const VectorXd & got, const VectorXd & want)
{
  return (got - want).cwiseAbs().maxCoeff() / std::max(1.0, want.cwiseAbs().maxCoeff());
}

// Returns false (after printing) when a check fails.
bool selfCheck(const Arm & arm, const pinocchio::Model & model, pinocchio::Data & data)
{
  const int n = arm.dof;
  VectorXd pi(10 * n);
  for (int i = 0; i < n; ++i)
    pi.segment<10>(10 * i) = model.inertias[static_cast<size_t>(i) + 1].toDynamicParameters();
  const VectorXd zero = VectorXd::Zero(n);
  double e_dynid = 0, e_split = 0, e_regr = 0, e_grav = 0;
  for (size_t k = 0; k < arm.q.size(); ++k)
  {
    const VectorXd tau = pinocchio::rnea(model, data, arm.q[k], arm.v[k], arm.a[k]);
    e_dynid = std::max(e_dynid, relErr(tau, arm.tau[k]));
    pinocchio::crba(model, data, arm.q[k]);
    MatrixXd m = data.M;
    m.triangularView<Eigen::StrictlyLower>() = m.transpose().triangularView<Eigen::StrictlyLower>();
    const VectorXd nle = pinocchio::nonLinearEffects(model, data, arm.q[k], arm.v[k]);
    e_split = std::max(e_split, relErr(m * arm.a[k] + nle, tau));
    const MatrixXd y = pinocchio::computeJointTorqueRegressor(model, data, arm.q[k], arm.v[k], arm.a[k]);
    e_regr = std::max(e_regr, relErr(y * pi, tau));
    const VectorXd g = pinocchio::computeGeneralizedGravity(model, data, arm.q[k]);
    e_grav = std::max(e_grav, relErr(g, pinocchio::rnea(model, data, arm.q[k], zero, zero)));
  }
  const double tol = 1e-9;
  bool ok = true;
  auto line = [&](const char * what, double e) {
    std::printf("# check %-8s %-24s worst %.3e over %zu samples %s\n", arm.name.c_str(), what, e,
                arm.q.size(), e < tol ? "ok" : "FAILED");
    ok = ok && e < tol; // a NaN fails too
  };
  line("rnea = dynid tau", e_dynid);
  line("M a + nle = rnea", e_split);
  line("Y pi = rnea", e_regr);
  line("g = rnea(q, 0, 0)", e_grav);
  return ok;
}

// Keeps the compiler from dropping a call's result or moving work across calls.
inline void clobber()
{
  asm volatile("" : : : "memory");
}
template<class T>
inline void escape(const T * p)
{
  asm volatile("" : : "g"(p) : "memory");
}

using Clock = std::chrono::steady_clock;

// dynid's time_per_call: ns per call of f(i), i = 0, 1, 2, ... (median over repetitions).
template<class F>
double timePerCall(const Timing & t, size_t pool, F && f)
{
  auto run = [&](size_t n) {
    const auto t0 = Clock::now();
    for (size_t i = 0; i < n; ++i)
      f(i);
    return std::chrono::duration<double>(Clock::now() - t0).count();
  };
  size_t n = pool;
  double s = run(n);
  while (s < 0.5 * t.target_s)
  {
    n *= 2;
    s = run(n);
  }
  n = std::max(pool, static_cast<size_t>(static_cast<double>(n) * t.target_s / s));
  n = (n + pool - 1) / pool * pool;
  run(n); // warm-up
  std::vector<double> per;
  for (int r = 0; r < std::max(1, t.reps); ++r)
    per.push_back(run(n) / static_cast<double>(n) * 1e9);
  std::sort(per.begin(), per.end());
  const size_t m = per.size();
  return m % 2 == 1 ? per[m / 2] : 0.5 * (per[m / 2 - 1] + per[m / 2]);
}

double envDouble(const char * name, double fallback)
{
  const char * s = std::getenv(name);
  return s && *s ? std::atof(s) : fallback;
}

} // namespace

int main(int argc, char ** argv)
{
  if (argc != 2)
  {
    std::fprintf(stderr, "usage: %s MODELS   (MODELS: output of `dynid bench-models`)\n", argv[0]);
    return 2;
  }
  try
  {
    Timing timing;
    std::vector<Arm> arms = readModels(argv[1], timing);
    timing.target_s = envDouble("PEERS_TARGET_MS", timing.target_s * 1e3) * 1e-3;
    timing.reps = static_cast<int>(envDouble("PEERS_REPS", timing.reps));
    std::printf("# Pinocchio %s (header-only), %s, %s\n", PINOCCHIO_VERSION, PEERS_CXX, PEERS_FLAGS);
    // The file name only: the report is committed, the harness's cache directory is this machine's.
    const std::string pool = argv[1];
    std::printf("# models and input pool: %s (dynid bench-models, in the harness's cache)\n",
                pool.substr(pool.find_last_of('/') + 1).c_str());
    std::printf("# timing: median of %d repetitions of ~%.1f ms, ns per call, single thread\n",
                timing.reps, timing.target_s * 1e3);

    std::vector<pinocchio::Model> models;
    std::vector<pinocchio::Data> datas;
    bool ok = true;
    for (const Arm & arm : arms)
    {
      models.push_back(buildModel(arm));
      datas.emplace_back(models.back());
      ok = selfCheck(arm, models.back(), datas.back()) && ok;
    }
    if (!ok)
    {
      std::printf("# self-check FAILED: not timing a model that differs from dynid's\n");
      std::fflush(stdout);
      std::fprintf(stderr, "pinocchio bench: self-check failed (see the `# check` lines)\n");
      return 1;
    }

    // Busy warm-up (dynid's Settings::warm_up), so the first measurement does not pay for the
    // CPU leaving its idle clock.
    {
      const Arm & arm = arms.front();
      const size_t mask = arm.q.size() - 1;
      const auto t0 = Clock::now();
      size_t i = 0;
      while (std::chrono::duration<double>(Clock::now() - t0).count() < timing.warm_up_s)
        for (int r = 0; r < 64; ++r, ++i)
        {
          pinocchio::rnea(models[0], datas[0], arm.q[i & mask], arm.v[i & mask], arm.a[i & mask]);
          clobber();
        }
    }

    std::vector<std::string> csv;
    std::printf("%-10s %-10s %12s\n", "ARM", "ALGO", "MEDIAN ns");
    for (size_t m = 0; m < arms.size(); ++m)
    {
      const Arm & arm = arms[m];
      const pinocchio::Model & model = models[m];
      pinocchio::Data & data = datas[m];
      const size_t pool = arm.q.size(), mask = pool - 1;
      auto report = [&](const char * algo, double ns) {
        std::printf("%-10s %-10s %12.1f\n", arm.name.c_str(), algo, ns);
        std::fflush(stdout);
        char buf[160];
        std::snprintf(buf, sizeof buf, "pinocchio,%s,%s,%.1f", arm.name.c_str(), algo, ns);
        csv.push_back(buf);
      };
      report("rnea", timePerCall(timing, pool, [&](size_t i) {
               const size_t k = i & mask;
               pinocchio::rnea(model, data, arm.q[k], arm.v[k], arm.a[k]);
               escape(data.tau.data());
             }));
      report("crba", timePerCall(timing, pool, [&](size_t i) {
               pinocchio::crba(model, data, arm.q[i & mask]);
               escape(data.M.data());
             }));
      report("nle", timePerCall(timing, pool, [&](size_t i) {
               const size_t k = i & mask;
               pinocchio::nonLinearEffects(model, data, arm.q[k], arm.v[k]);
               escape(data.nle.data());
             }));
      report("regressor", timePerCall(timing, pool, [&](size_t i) {
               const size_t k = i & mask;
               pinocchio::computeJointTorqueRegressor(model, data, arm.q[k], arm.v[k], arm.a[k]);
               escape(data.jointTorqueRegressor.data());
             }));
      report("gravity", timePerCall(timing, pool, [&](size_t i) {
               pinocchio::computeGeneralizedGravity(model, data, arm.q[i & mask]);
               escape(data.g.data());
             }));
      report("aba", timePerCall(timing, pool, [&](size_t i) {
               const size_t k = i & mask;
               pinocchio::aba(model, data, arm.q[k], arm.v[k], arm.a[k]);
               escape(data.ddq.data());
             }));
      report("minverse", timePerCall(timing, pool, [&](size_t i) {
               pinocchio::computeMinverse(model, data, arm.q[i & mask]);
               escape(data.Minv.data());
             }));
      report("rnea_derivatives", timePerCall(timing, pool, [&](size_t i) {
               const size_t k = i & mask;
               pinocchio::computeRNEADerivatives(model, data, arm.q[k], arm.v[k], arm.a[k]);
               escape(data.dtau_dq.data());
               escape(data.dtau_dv.data());
             }));
      report("aba_derivatives", timePerCall(timing, pool, [&](size_t i) {
               const size_t k = i & mask;
               pinocchio::computeABADerivatives(model, data, arm.q[k], arm.v[k], arm.a[k]);
               escape(data.ddq_dq.data());
               escape(data.ddq_dv.data());
               escape(data.Minv.data());
             }));
    }
    for (const std::string & line : csv)
      std::printf("%s\n", line.c_str());
    return 0;
  }
  catch (const std::exception & e)
  {
    std::fprintf(stderr, "pinocchio bench: %s\n", e.what());
    return 2;
  }
}
