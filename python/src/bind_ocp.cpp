// SPDX-License-Identifier: BSD-3-Clause
// The shipped optimal control problems (bench/ocp_spec/benchmark_ocps.hpp, problems of
// docs/benchmark-spec.md and of the formation controller): leader L, follower F2 and
// the reduced follower F2, each as an RTI solver with numpy vectors in and out.
#include <pybind11/eigen.h>
#include <pybind11/stl.h>

#include <array>
#include <string>

#include "bench/ocp_spec/benchmark_ocps.hpp"
#include "python/src/bindings.hpp"

namespace py = pybind11;

namespace fnmpc::python {
namespace {

namespace bm = fnmpc::bench;
constexpr int kNeighbours = 2;  // the formation controller's followers see two neighbours
using Neighbours = std::array<bm::NeighbourState, kNeighbours>;

ocp::TargetFrame FrameFrom(const std::string& name) {
  if (name == "inertial") return ocp::TargetFrame::kInertial;
  if (name == "control") return ocp::TargetFrame::kControl;
  throw std::invalid_argument("frame must be 'inertial' or 'control', got '" + name + "'");
}

template <class Vector>
void CheckFinite(const Vector& v, const char* what) {
  if (!v.allFinite()) throw std::invalid_argument(std::string(what) + " has NaN or Inf entries");
}

template <class Solver>
void CheckStage(const Solver& s, int k, int last, const char* what) {
  if (k < 0 || k > last) {
    throw std::out_of_range(std::string(what) + ": stage " + std::to_string(k) + " outside 0.." +
                            std::to_string(last));
  }
  (void)s;
}

py::dict Stats(const rti::RtiStats& s) {
  py::dict d;
  d["status"] = std::string(rti::ToString(s.status));
  d["qp_status"] = std::string(qp::ToString(s.qp_status));
  d["sqp_iterations"] = s.sqp_iterations;
  d["qp_iterations"] = s.qp_iterations;
  d["unconstrained_step"] = s.unconstrained_step;
  d["fallback"] = s.fallback;
  d["fallback_count"] = s.fallback_count;
  d["kkt"] = s.kkt;
  d["time_prepare"] = s.time_prepare;
  d["time_feedback"] = s.time_feedback;
  d["time_total"] = s.time_total;
  return d;
}

/// The methods every solver shares (RtiSolver<Problem>).
template <class Solver>
void BindSolverMethods(py::class_<Solver>& c) {
  using P = Solver;  // kNx, kNu, kNy, kNyN, kNp
  using X = typename Solver::X;
  using U = typename Solver::U;
  using Y = typename Solver::Y;
  using YN = typename Solver::YN;
  using Par = typename Solver::P;
  c.def_property_readonly_static(
       "nx", [](py::object) { return P::kNx; }, "state size")
      .def_property_readonly_static(
          "nu", [](py::object) { return P::kNu; },
          "input size: thrust [N], roll and pitch references [rad]")
      .def_property_readonly_static(
          "ny", [](py::object) { return P::kNy; }, "stage residuals")
      .def_property_readonly_static(
          "nyn", [](py::object) { return P::kNyN; }, "terminal residuals")
      .def_property_readonly_static(
          "np", [](py::object) { return P::kNp; }, "stage parameters (p[0]: yaw reference [rad])")
      .def_property_readonly("horizon", [](const Solver& s) { return s.settings().horizon; })
      .def_property_readonly("sample_time",
                             [](const Solver& s) { return s.settings().sample_time; })
      .def(
          "set_reference",
          [](Solver& s, int k, const Y& y) {
            CheckStage(s, k, s.settings().horizon - 1, "set_reference");
            CheckFinite(y, "reference");
            s.SetReference(k, y);
          },
          py::arg("k"), py::arg("y"), "Reference (ny,) of stage k = 0..N-1.")
      .def(
          "set_terminal_reference",
          [](Solver& s, const YN& y) {
            CheckFinite(y, "terminal reference");
            s.SetTerminalReference(y);
          },
          py::arg("y"), "Terminal reference (nyn,).")
      .def(
          "set_parameters",
          [](Solver& s, int k, const Par& p) {
            CheckStage(s, k, s.settings().horizon, "set_parameters");
            CheckFinite(p, "parameters");
            s.SetParameters(k, p);
          },
          py::arg("k"), py::arg("p"), "Stage parameters (np,) of node k = 0..N.")
      .def(
          "set_weights",
          [](Solver& s, const Y& w, const YN& wn) {
            CheckFinite(w, "weights");
            CheckFinite(wn, "terminal weights");
            s.SetWeights(w, wn);
          },
          py::arg("w"), py::arg("w_terminal"),
          "Diagonal weights of the stage (ny,) and terminal (nyn,) residuals.")
      .def(
          "set_input_bounds",
          [](Solver& s, int k, const U& lb, const U& ub) {
            CheckStage(s, k, s.settings().horizon - 1, "set_input_bounds");
            s.SetInputBounds(k, lb, ub);
          },
          py::arg("k"), py::arg("lb"), py::arg("ub"), "Input bounds (nu,) of stage k.")
      .def(
          "initialize_guess",
          [](Solver& s, const X& x0, const U& u) {
            CheckFinite(x0, "x0");
            CheckFinite(u, "u");
            s.InitializeGuess(x0, u);
          },
          py::arg("x0"), py::arg("u"),
          "Every node at x0, every control at u; the next step() iterates to convergence.")
      .def(
          "step",
          [](Solver& s, const X& x0) {
            CheckFinite(x0, "x0");
            U u = U::Zero();
            s.Step(x0, &u);
            return u;
          },
          py::arg("x0"),
          "One RTI step from the measured state x0 (nx,): returns the first control (nu,). "
          "On a solver failure the shifted previous control is returned and stats['fallback'] "
          "is True. Call shift() before the next sampling time.")
      .def("shift", &Solver::Shift, "Warm start for the next sampling time.")
      .def(
          "kkt", [](Solver& s, const X& x0) { return s.ComputeKkt(x0); }, py::arg("x0"),
          "KKT value of the current iterate (benchmark spec definition).")
      .def_property_readonly(
          "states",
          [](const Solver& s) {
            Eigen::Matrix<double, Eigen::Dynamic, P::kNx, Eigen::RowMajor> out(
                static_cast<Eigen::Index>(s.states().size()), P::kNx);
            for (std::size_t k = 0; k < s.states().size(); ++k)
              out.row(static_cast<Eigen::Index>(k)) = s.states()[k].transpose();
            return out;
          },
          "Predicted state trajectory (N + 1, nx).")
      .def_property_readonly(
          "inputs",
          [](const Solver& s) {
            Eigen::Matrix<double, Eigen::Dynamic, P::kNu, Eigen::RowMajor> out(
                static_cast<Eigen::Index>(s.inputs().size()), P::kNu);
            for (std::size_t k = 0; k < s.inputs().size(); ++k)
              out.row(static_cast<Eigen::Index>(k)) = s.inputs()[k].transpose();
            return out;
          },
          "Predicted controls (N, nu).")
      .def_property_readonly(
          "stats", [](const Solver& s) { return Stats(s.stats()); },
          "Statistics of the last step(): status, qp_status, sqp_iterations, qp_iterations, "
          "unconstrained_step, fallback, fallback_count, kkt (-1 when not computed), "
          "time_prepare, time_feedback, time_total [s].");
}

void BindSettings(py::module_& m) {
  py::class_<rti::RtiSettings>(m, "RtiSettings",
                               "RTI solver settings; the default is the benchmark spec "
                               "(Ts = 0.05 s, N = 15, 2 RK4 steps, one SQP iteration).")
      .def(py::init([] { return bm::SpecSettings(); }))
      .def_readwrite("horizon", &rti::RtiSettings::horizon)
      .def_readwrite("sample_time", &rti::RtiSettings::sample_time, "[s]")
      .def_readwrite("integrator_steps", &rti::RtiSettings::integrator_steps)
      .def_readwrite("max_initial_iterations", &rti::RtiSettings::max_initial_iterations)
      .def_readwrite("kkt_threshold", &rti::RtiSettings::kkt_threshold)
      .def_readwrite("max_iterations", &rti::RtiSettings::max_iterations)
      .def_readwrite("cpu_budget", &rti::RtiSettings::cpu_budget, "[s]")
      .def("validate", &rti::RtiSettings::Validate);
  py::class_<bm::NeighbourState>(m, "NeighbourState", "What a follower senses of a neighbour.")
      .def(py::init([](const Vec3& rel_pos, const Vec3& vel, double yaw, double yaw_rate) {
             return bm::NeighbourState{rel_pos, vel, yaw, yaw_rate};
           }),
           py::arg("rel_pos") = Vec3::Zero(), py::arg("vel") = Vec3::Zero(), py::arg("yaw") = 0.0,
           py::arg("yaw_rate") = 0.0)
      .def_readwrite("rel_pos", &bm::NeighbourState::rel_pos, "p_j - p_self (3,) [m]")
      .def_readwrite("vel", &bm::NeighbourState::vel, "(3,) [m/s]")
      .def_readwrite("yaw", &bm::NeighbourState::yaw, "[rad]")
      .def_readwrite("yaw_rate", &bm::NeighbourState::yaw_rate, "[rad/s]");
  py::class_<bm::ReferenceTrajectory>(m, "ReferenceTrajectory",
                                      "The benchmark leader reference (quintic legs through "
                                      "six waypoints): 'nominal' or 'aggressive'.")
      .def(py::init([](const std::string& name) {
             if (name == "nominal") return bm::ReferenceTrajectory(bm::Scenario::kNominal);
             if (name == "aggressive") return bm::ReferenceTrajectory(bm::Scenario::kAggressive);
             throw std::invalid_argument("scenario must be 'nominal' or 'aggressive', got '" +
                                         name + "'");
           }),
           py::arg("scenario") = "nominal")
      .def(
          "sample",
          [](const bm::ReferenceTrajectory& r, double t) {
            Vec3 p, v;
            r.Sample(t, &p, &v);
            return py::make_tuple(p, v);
          },
          py::arg("t"), "(position (3,) [m], velocity (3,) [m/s]) at time t [s].");
}

Neighbours ToNeighbours(const std::vector<bm::NeighbourState>& v) {
  if (v.size() != kNeighbours) {
    throw std::invalid_argument("expected " + std::to_string(kNeighbours) + " neighbours, got " +
                                std::to_string(v.size()));
  }
  return {v[0], v[1]};
}

}  // namespace

void BindOcp(py::module_& m) {
  BindSettings(m);

  py::class_<bm::LeaderSolver> leader(
      m, "LeaderOcp",
      "Problem L (leader tracking): x = [p (3), v (3), roll, pitch, yaw], u = [thrust, "
      "roll_ref, pitch_ref], y = [p, v, roll, pitch, T - m g, roll_ref, pitch_ref]. Built "
      "with the spec's weights and bounds, initial guess at rest at x0.");
  leader.def(py::init([](const Vec<9>& x0, const rti::RtiSettings& settings) {
               CheckFinite(x0, "x0");
               return bm::MakeLeaderSolver(x0, settings);
             }),
             py::arg("x0"), py::arg("settings") = bm::SpecSettings());
  BindSolverMethods(leader);
  leader.def(
      "set_references",
      [](bm::LeaderSolver& s, const bm::ReferenceTrajectory& ref, double t) {
        bm::SetLeaderReferences(&s, ref, t);
      },
      py::arg("trajectory"), py::arg("t"),
      "References of every stage for the control step starting at time t [s].");

  using Follower = bm::FollowerSolver<kNeighbours>;
  py::class_<Follower> follower(
      m, "FollowerOcp",
      "Problem F2 (follower with two neighbours in its state): x = [v (3), roll, pitch, yaw, "
      "then per neighbour dx_j (3), v_j (3), yaw_j, yaw_rate_j], nx = 22.");
  follower.def(py::init([](const Vec<6>& own, const std::vector<bm::NeighbourState>& nb,
                           const rti::RtiSettings& settings, const std::string& frame) {
                 return bm::MakeFollowerSolver<kNeighbours>(own, ToNeighbours(nb), settings,
                                                            FrameFrom(frame));
               }),
               py::arg("own"), py::arg("neighbours"), py::arg("settings") = bm::SpecSettings(),
               py::arg("frame") = "inertial",
               "own = [v (3), roll, pitch, yaw]; neighbours: two NeighbourState; frame of the "
               "desired offsets: 'inertial' or 'control'.");
  BindSolverMethods(follower);
  m.def(
      "follower_state",
      [](const Vec<6>& own, const std::vector<bm::NeighbourState>& nb) {
        return bm::FollowerState<kNeighbours>(own, ToNeighbours(nb));
      },
      py::arg("own"), py::arg("neighbours"), "The F2 state (22,) from own state and neighbours.");
  m.def(
      "desired_offsets",
      [] {
        const auto d = bm::DesiredOffsets<kNeighbours>();
        return std::vector<Vec3>(d.begin(), d.end());
      },
      "The benchmark's desired offsets d_j of the two neighbours [m].");

  using Reduced = bm::ReducedFollowerSolver<kNeighbours>;
  py::class_<Reduced> reduced(
      m, "ReducedFollowerOcp",
      "Reduced follower (the formation controller's): the neighbours' constant-velocity "
      "predictions are stage parameters, x = [s (3), v (3), roll, pitch, yaw] with s the "
      "displacement since now, np = 13.");
  reduced.def(py::init([](const Vec<6>& own, const std::vector<bm::NeighbourState>& nb,
                          const rti::RtiSettings& settings, const std::string& frame) {
                return bm::MakeReducedFollowerSolver<kNeighbours>(own, ToNeighbours(nb), settings,
                                                                  FrameFrom(frame));
              }),
              py::arg("own"), py::arg("neighbours"), py::arg("settings") = bm::SpecSettings(),
              py::arg("frame") = "inertial");
  BindSolverMethods(reduced);
  reduced.def(
      "set_stage",
      [](Reduced& s, const Vec<6>& own, const std::vector<bm::NeighbourState>& nb) {
        return bm::SetReducedFollowerStage<kNeighbours>(&s, own, ToNeighbours(nb));
      },
      py::arg("own"), py::arg("neighbours"),
      "Sets the stage parameters and bounds from the present neighbour states; returns "
      "x0 = [0, v, angles] (9,) for step().");
}

}  // namespace fnmpc::python
