// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/experiment/run_loop.hpp"

#include <filesystem>

#include "fnmpc/experiment/closed_loop.hpp"
#include "fnmpc/experiment/run_log.hpp"
#include "fnmpc/experiment/run_observers.hpp"

namespace fnmpc::experiment {

RunRecord RecordRun(const config::ScenarioConfig& sc, const RunOptions& options,
                    const std::string& dir) {
  ClosedLoop loop(sc, options);
  const int nv = loop.vehicles();
  std::filesystem::create_directories(dir);
  if (sc.reality.enabled) WritePlantFiles(sc, loop.world_config(), dir);
  RunRecord rec;
  rec.duration = loop.duration();
  rec.vehicles.resize(nv);
  rec.downed.resize(nv);
  rec.pairs.resize(static_cast<std::size_t>(nv) * static_cast<std::size_t>(nv - 1) / 2);
  for (int i = 0; i < nv; ++i) {
    rec.vehicles[i].nb_errors.resize(sc.vehicles[i].neighbours.size());
    rec.vehicles[i].nb_steady.resize(sc.vehicles[i].neighbours.size());
  }
  // The monitors, in the order they are called (the flight record reads the impacts, the
  // CSV log the formation errors).
  ImpactObserver impacts(&rec);
  SeparationObserver separations(&rec);
  FlightRecordObserver flight(&rec);
  EnvelopeObserver envelope(&rec);
  FormationErrorObserver errors(&rec, nv);
  CsvLogObserver csv(sc, dir, &errors);
  ProgressObserver progress(options.label);
  for (ClosedLoopObserver* o : std::initializer_list<ClosedLoopObserver*>{
           &impacts, &separations, &flight, &envelope, &errors, &csv}) {
    loop.AddObserver(o);
  }
  if (options.progress) {
    loop.AddObserver(&progress);
    loop.SetEventSink([&progress](double t, const std::string& what) { progress.Event(t, what); });
  }
  loop.Run();

  rec.stopped = loop.stopped();
  rec.sim_error = loop.sim_error();
  const sim::World& world = loop.world().world();
  for (int i = 0; i < nv; ++i) {
    const formation::VehicleController* ctrl = loop.controller(i);
    rec.controlled.push_back(ctrl ? 1 : 0);
    rec.estimator_rejections.push_back(ctrl ? ctrl->estimator_rejections() : 0);
    if (ctrl) rec.vehicles[i].neighbour_departures = ctrl->neighbour_departures();
    rec.final_state.push_back(world.GetTrueState(i));
    rec.final_autopilot.push_back(world.GetAutopilotStatus(i));
  }
  const FaultInjector& injector = loop.world().injector();
  for (std::size_t w = 0; w < sc.faults.sensor_dropouts.size(); ++w) {
    rec.dropped.push_back(injector.dropped(w));
  }
  rec.measurements = injector.measurements();
  rec.outliers = injector.outliers();
  if (loop.link() != nullptr) {
    rec.link = true;
    rec.link_stats = loop.link()->statistics();
  }
  return rec;
}

}  // namespace fnmpc::experiment
