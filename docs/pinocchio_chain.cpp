// Pinocchio compiled, for `pymr bench chain --pinocchio-cpp EXE`: the serial chain of N uniform
// rods of pymr.scenes.serial_chain (revolute axes alternating z and x, hanging under -y
// gravity). Reads N, q and qd from stdin; prints ABA's accelerations, then the median CPU
// time (us) of one ABA and of one CRBA + nonLinearEffects + Cholesky solve.
//
// Build against the pip package `pin` (its cmeel prefix) and Eigen (libeigen3-dev):
//   P=$(python -c "import cmeel, os; print(os.path.join(os.path.dirname(cmeel.__file__), '..', 'cmeel.prefix'))")
//   g++ -O3 -DNDEBUG -std=c++17 -DBOOST_MPL_LIMIT_LIST_SIZE=30 -DBOOST_MPL_LIMIT_VECTOR_SIZE=30 \
//     -DBOOST_MPL_CFG_NO_PREPROCESSED_HEADERS -DBOOST_FUSION_INVOKE_MAX_ARITY=12 -I$P/include \
//     -I/usr/include/eigen3 docs/pinocchio_chain.cpp -L$P/lib -lpinocchio_default -Wl,-rpath,$P/lib \
//     -o pinocchio_chain
#include <pinocchio/multibody.hpp>

#include <pinocchio/algorithm/aba.hpp>
#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/algorithm/rnea.hpp>
#include <pinocchio/algorithm/cholesky.hpp>
#include <ctime>
#include <iostream>
#include <algorithm>
#include <vector>
using namespace pinocchio;
static double cpu() { timespec t; clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t); return t.tv_sec + 1e-9 * t.tv_nsec; }
int main() {
  int n; std::cin >> n;
  Eigen::VectorXd q(n), v(n), tau = Eigen::VectorXd::Zero(n);
  for (int i = 0; i < n; ++i) std::cin >> q[i];
  for (int i = 0; i < n; ++i) std::cin >> v[i];
  Model model; JointIndex parent = 0;
  const double L = 0.5, m = 1.0, r = 0.02;
  for (int i = 0; i < n; ++i) {
    SE3 placement(Eigen::Matrix3d::Identity(), Eigen::Vector3d(i == 0 ? 0.0 : L, 0, 0));
    JointIndex j = (i % 2 == 0) ? model.addJoint(parent, JointModelRZ(), placement, "j" + std::to_string(i))
                                : model.addJoint(parent, JointModelRX(), placement, "j" + std::to_string(i));
    Eigen::Vector3d diag(0.5 * m * r * r, m * L * L / 12, m * L * L / 12);
    model.appendBodyToJoint(j, Inertia(m, Eigen::Vector3d(L / 2, 0, 0), diag.asDiagonal()), SE3::Identity());
    parent = j;
  }
  model.gravity.linear(Eigen::Vector3d(0, -9.81, 0));
  Data data(model);
  aba(model, data, q, v, tau);
  std::cout.precision(17);
  for (int i = 0; i < n; ++i) std::cout << data.ddq[i] << (i + 1 < n ? " " : "\n");
  int reps = std::max(200, 400000 / n);
  auto med = [&](auto f) { std::vector<double> s; for (int k = 0; k < 7; ++k) { double c0 = cpu(); for (int r = 0; r < reps; ++r) f(); s.push_back((cpu() - c0) / reps); } std::sort(s.begin(), s.end()); return s[3]; };
  double t_aba = med([&] { aba(model, data, q, v, tau); });
  Eigen::VectorXd a(n);
  double t_crba = med([&] { crba(model, data, q); nonLinearEffects(model, data, q, v); cholesky::decompose(model, data); a = -data.nle; cholesky::solve(model, data, a); });
  std::cout << t_aba * 1e6 << " " << t_crba * 1e6 << "\n";
}
