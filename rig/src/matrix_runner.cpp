#include "strut/rig/matrix_runner.h"

#include <spdlog/fmt/fmt.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <thread>

namespace strut::rig {

namespace {

std::int64_t Now() { return daq::MonotonicNs(); }

std::int64_t Ns(std::chrono::nanoseconds d) { return d.count(); }
std::int64_t Seconds(double s) { return static_cast<std::int64_t>(s * 1e9); }

// Ends the experiment in progress: a trip beyond "indicate", a device lost, a stop request.
struct Interrupt {
  Trip trip;
};

}  // namespace

bool RunnerOptions::IsValid(std::string* error) const {
  auto fail = [&](std::string m) {
    if (error) *error = std::move(m);
    return false;
  };
  if (periods < 1 || periods > 100000) return fail(fmt::format("periods {} is outside 1..100000", periods));
  if (ramp_cycles < 0 || ramp_cycles > daq::SetPoint::kMaxRampCycles)
    return fail(fmt::format("ramp_cycles {} is outside 0..{}", ramp_cycles, daq::SetPoint::kMaxRampCycles));
  if (!(static_rate > 0.0 && std::isfinite(static_rate))) return fail(fmt::format("static_rate {} m/s must be positive", static_rate));
  if (loop.count() < 1 || loop.count() > 1000) return fail(fmt::format("loop {} ms is outside 1..1000 ms", loop.count()));
  if (controller_grace.count() < 1) return fail("controller_grace must be at least 1 ms");
  if (settle_margin.count() < 0) return fail("settle_margin must not be negative");
  if (max_attempts < 1) return fail(fmt::format("max_attempts {} must be at least 1", max_attempts));
  if (pressure_reference != "gauge" && pressure_reference != "absolute")
    return fail(fmt::format("pressure_reference '{}' is neither \"gauge\" nor \"absolute\"", pressure_reference));
  if (!(position_tolerance > 0.0)) return fail("position_tolerance must be positive");
  if (!(stream_speed > 0.0 && std::isfinite(stream_speed)))
    return fail(fmt::format("stream_speed {} must be positive", stream_speed));
  std::string steady_error;
  if (!steady.IsValid(&steady_error)) return fail(steady_error);
  if (top_out && !top_out->IsValid(&steady_error)) return fail(steady_error);
  return true;
}

std::string_view ToString(RunPhase phase) {
  switch (phase) {
    case RunPhase::kStarting:
      return "starting";
    case RunPhase::kReference:
      return "top-out reference";
    case RunPhase::kMoving:
      return "moving to static";
    case RunPhase::kRampIn:
      return "ramp in";
    case RunPhase::kSettling:
      return "settling";
    case RunPhase::kRecording:
      return "recording";
    case RunPhase::kRampOut:
      return "ramp out";
    case RunPhase::kSafing:
      return "safing";
    case RunPhase::kDone:
      return "done";
  }
  return "unknown";
}

std::string_view ToString(RunOutcome outcome) {
  switch (outcome) {
    case RunOutcome::kComplete:
      return "complete";
    case RunOutcome::kPaused:
      return "paused";
    case RunOutcome::kAborted:
      return "aborted";
  }
  return "unknown";
}

std::string RunItem::label() const { return attempt <= 1 ? entry.label : fmt::format("{}-{}", entry.label, attempt); }

std::vector<RunItem> RemainingExperiments(const std::vector<MatrixEntry>& matrix, const daq::Session& so_far) {
  std::map<std::string, int> attempts;
  std::map<std::string, bool> done;
  for (const daq::Experiment& e : so_far.experiments) {
    const auto it = e.extra_attributes.find("matrix_label");
    const std::string label = it != e.extra_attributes.end() ? it->second : e.label;
    attempts[label] += 1;
    if (e.status == "complete") done[label] = true;
  }
  std::vector<RunItem> items;
  for (const MatrixEntry& m : matrix) {
    if (done[m.label]) continue;
    RunItem item{m, attempts[m.label] + 1};
    // A label the session holds already (e.g. an experiment recorded outside the runner) is skipped over.
    while (so_far.find_experiment(item.label()) != nullptr) ++item.attempt;
    items.push_back(item);
  }
  return items;
}

struct MatrixRunner::Impl {
  //! Blocks read in one loop at most: a second of the stream at the default block size.
  static constexpr int kMaxBlocksPerLoop = 100;

  Impl(MatrixRunner& owner, daq::ActuatorController& c, daq::AcquisitionModule& a, daq::Recorder& r, SafetyConfig s,
       RunnerOptions o)
      : owner(owner), controller(c), acquisition(a), recorder(r), safety(std::move(s), ChannelNames(a), o.stream_speed),
        options(std::move(o)) {}

  static std::vector<std::string> ChannelNames(const daq::AcquisitionModule& a) {
    std::vector<std::string> names;
    for (const daq::ChannelDescriptor& c : a.description().channels) names.push_back(c.name);
    return names;
  }

  MatrixRunner& owner;
  daq::ActuatorController& controller;
  daq::AcquisitionModule& acquisition;
  daq::Recorder& recorder;
  SafetyMonitor safety;
  RunnerOptions options;
  int stroke_k = -1, force_k = -1, pressure_k = -1;

  // The loop's view of the devices.
  daq::ControllerStatus status;
  bool have_status = false;
  std::int64_t controller_failing_since = 0;  // 0: the last call succeeded
  bool controller_lost = false;
  bool acquisition_lost = false;
  bool safing = false;
  bool disarmed = false;
  Progress progress;
  std::int64_t last_progress_ns = 0;
  RunReport* report = nullptr;

  // The experiment in progress.
  struct Current {
    RunItem item;
    long spp = 0;  // samples per cycle
    long wanted = 0;
    std::optional<CycleSummariser> summariser;
    std::optional<SteadyStateDetector> detector;
    std::vector<CycleSummary> cycles;
    bool summarising = false;
    bool open = false;  // begun in the recorder
    long recorded = 0;
    std::optional<std::int64_t> time_origin;    // the first recorded sample's stream time
    std::optional<std::int64_t> stream_origin;  // the first summarised sample's stream time
    std::int64_t full_amplitude_ns = 0;         // when the controller was seen at full amplitude
    long first_recorded_cycle = -1;
    bool finished = false;
  };
  std::optional<Current> current;

  // The top-out reference's search in progress: its samples on the recorded clock.
  struct Reference {
    explicit Reference(const TopOutOptions& o) : options(o), detector(o) {}
    TopOutOptions options;
    TopOutDetector detector;
    bool collecting = false;
    std::optional<std::int64_t> origin;  // the first sample's stream time
    std::vector<double> time, stroke, force;
  };
  std::optional<Reference> reference;

  // ---- events and trips

  void Event(std::string_view kind, const std::string& text, std::int64_t t = 0) {
    if (owner.on_event) owner.on_event(kind, text);
    try {
      recorder.Event(t != 0 ? t : Now(), kind, text);
    } catch (const daq::RecorderError& e) {
      if (!safing) throw;
      spdlog::error("{}", e.what());
    }
  }

  void Handle(const Trip& trip) {
    if (trip.action == SafetyAction::kIndicate) {
      spdlog::warn("{}: {} (indicate)", trip.detector, trip.text);
      Event("trip", fmt::format("{}: {} (action indicate)", trip.detector, trip.text), trip.monotonic_ns);
      return;
    }
    if (safing) {  // already going to the safe state: noted, nothing more to do
      spdlog::warn("{}: {} (while safing)", trip.detector, trip.text);
      Event("trip", fmt::format("{}: {} (while safing after an earlier trip)", trip.detector, trip.text), trip.monotonic_ns);
      return;
    }
    throw Interrupt{trip};
  }

  // ---- the loop

  void SetPhase(RunPhase phase) {
    progress.phase = phase;
    ReportProgress(true);
  }

  void ReportProgress(bool force) {
    if (!owner.on_progress) return;
    const std::int64_t now = Now();
    if (!force && now - last_progress_ns < 100'000'000) return;
    last_progress_ns = now;
    progress.margins = safety.TakeMargins();
    progress.stroke = status.stroke;
    progress.force = status.force;
    if (current) {
      progress.cycles = static_cast<long>(current->cycles.size());
      progress.periods_recorded = current->spp > 0 ? current->recorded / current->spp : 0;
      progress.steady_measure = current->detector ? current->detector->verdict().measure
                                                  : std::numeric_limits<double>::infinity();
      progress.steady.reset();
      if (current->detector) progress.steady = current->detector->verdict();
    }
    owner.on_progress(progress);
  }

  void PollController() {
    if (controller_lost) return;
    const std::int64_t now = Now();
    try {
      controller.Heartbeat();
      status = controller.ReadStatus();
      have_status = true;
      controller_failing_since = 0;
    } catch (const daq::DeviceError& e) {
      if (controller_failing_since == 0) controller_failing_since = now;
      if (now - controller_failing_since < Ns(options.controller_grace)) {
        spdlog::debug("controller: {}", e.what());
        return;
      }
      controller_lost = true;
      Handle(Trip{"controller-lost", SafetyAction::kInterlock, now,
                  fmt::format("no answer from the controller for {} ms: {}",
                              (now - controller_failing_since) / 1'000'000, e.what())});
      return;
    }
    for (const Trip& t : safety.CheckStatus(status, now)) Handle(t);
  }

  void Step() {
    if (!acquisition_lost) {
      // Every block that has arrived, not one a loop: a block is 10 ms of the stream, and a loop
      // with a controller round trip can take longer (an accelerated stream, a loaded machine);
      // reading one a loop let the backlog grow until the samples were stale and the cycles were
      // cut from samples older than the controller's status. Bounded, so the heartbeat goes on.
      std::chrono::nanoseconds wait = options.loop;
      for (int k = 0; k < kMaxBlocksPerLoop; ++k) {
        daq::AcquiredBlock block;
        try {
          block = acquisition.Read(wait);
        } catch (const daq::DeviceError& e) {
          acquisition_lost = true;
          Handle(Trip{"acquisition-lost", SafetyAction::kStop, Now(), fmt::format("the acquisition stream failed: {}", e.what())});
          break;
        }
        HandleBlock(block);
        if (block.empty()) break;
        wait = std::chrono::nanoseconds(0);
      }
      // Judged when the stream has just been read: a slow controller call after it (a Modbus
      // response timeout is 500 ms) must not count as the stream's silence.
      if (!acquisition_lost) {
        if (auto t = safety.CheckStale(Now())) Handle(*t);
      }
    } else {
      std::this_thread::sleep_for(options.loop);
    }
    PollController();
    ReportProgress(false);
    if (owner.stop_.load() && !safing) {
      throw Interrupt{Trip{"operator-stop", SafetyAction::kHold, Now(), "stop requested by the operator"}};
    }
  }

  void HandleBlock(const daq::AcquiredBlock& block) {
    if (owner.on_block) owner.on_block(block);
    for (const daq::AcquisitionEvent& e : block.events) Event(daq::ToString(e.kind), e.text, e.monotonic_ns);
    // The block is recorded first and checked after, so that a trip keeps the samples that caused it.
    RecordBlock(block);
    CollectReference(block);
    for (const Trip& t : safety.CheckBlock(block)) Handle(t);
  }

  void RecordBlock(const daq::AcquiredBlock& block) {
    if (!current || !current->summarising || current->finished || block.empty()) return;
    Current& c = *current;
    if (block.lost_before > 0 || block.quality.has(daq::Quality::kSequenceGap)) {
      c.summariser->Restart();
      if (c.open) AbortRecording(fmt::format("{} sample sets lost before sample set {}", block.lost_before, block.first_index));
    }
    const std::size_t n = block.size();
    std::size_t pos = 0;
    // A stream that arrives late (a starved receiver, a simulated rig at 25x where the ramp is
    // 40 ms of wall time) still holds samples of the ramp, or from before it, after the controller
    // reports full amplitude: cycles start from the first sample stamped after that report.
    while (!c.stream_origin && pos < n && block.time_ns[pos] < c.full_amplitude_ns) ++pos;
    const auto slice = [&](int k, std::size_t from, std::size_t count) {
      return k < 0 ? std::span<const double>() : std::span<const double>(block.values[k]).subspan(from, count);
    };
    while (pos < n && !c.finished) {
      const std::size_t k = std::min<std::size_t>(n - pos, static_cast<std::size_t>(c.spp - c.summariser->filled()));
      if (c.open) {
        const std::size_t take = std::min<std::size_t>(k, static_cast<std::size_t>(c.wanted - c.recorded));
        daq::SampleBlock recorded = daq::RecordedBlock(block, pos, pos + take);
        if (!c.time_origin && !recorded.monotonic_ns.empty()) c.time_origin = recorded.monotonic_ns.front();
        if (c.time_origin) daq::ToRecordedTime(recorded, *c.time_origin, options.stream_speed);
        recorder.Append(recorded);
        c.recorded += static_cast<long>(take);
      }
      // The cycles' times on the recorded clock, so the detector's seconds are the damper's.
      if (!c.stream_origin) c.stream_origin = block.time_ns[pos];
      std::vector<std::int64_t> times(block.time_ns.begin() + static_cast<std::ptrdiff_t>(pos),
                                      block.time_ns.begin() + static_cast<std::ptrdiff_t>(pos + k));
      daq::ToRecordedTime(times, *c.stream_origin, options.stream_speed);
      const auto done = c.summariser->Add(times,
                                          slice(stroke_k, pos, k), slice(force_k, pos, k), slice(pressure_k, pos, k));
      pos += k;
      for (const CycleSummary& cycle : done) OnCycle(cycle);
    }
  }

  void CollectReference(const daq::AcquiredBlock& block) {
    if (!reference || !reference->collecting || block.empty()) return;
    Reference& r = *reference;
    if (!r.origin) r.origin = block.time_ns.front();
    for (std::size_t i = 0; i < block.size(); ++i) {
      const double y = block.values[stroke_k][i], f = block.values[force_k][i];
      r.time.push_back(static_cast<double>(block.time_ns[i] - *r.origin) * 1e-9 * options.stream_speed);
      r.stroke.push_back(y);
      r.force.push_back(f);
      r.detector.Add(y, f);
    }
    progress.steady_measure = r.detector.measure();
  }

  void OnCycle(const CycleSummary& cycle) {
    Current& c = *current;
    c.cycles.push_back(cycle);
    if (auto t = safety.CheckCycle(cycle, c.item.entry.amplitude, cycle.end_ns)) Handle(*t);
    if (!c.open) {
      const SteadyStateVerdict& v = c.detector->Add(cycle);
      if (v.done()) BeginRecording();
      return;
    }
    if (c.recorded >= c.wanted) FinishRecording();
  }

  daq::ExperimentDescriptor Descriptor() const {
    const Current& c = *current;
    daq::Experiment h = PeriodicExperimentOf(c.item.entry, options.periods, RecordedRate());
    h.label = c.item.label();  // a repeat's label names its attempt
    h.extra_attributes["matrix_label"] = c.item.entry.label;
    h.extra_attributes["attempt"] = std::to_string(c.item.attempt);
    // When the recording began (UTC, to the second): a charge that leaks over a session shows as a
    // drift with this time (docs/rig-run.md).
    h.extra_attributes["started_utc"] = daq::UtcNowIso8601();
    return daq::AcquiredExperiment(std::move(h), acquisition.description(), options.pressure_reference);
  }

  //! The rate the session states: the stream's, on the recorded clock.
  double RecordedRate() const { return acquisition.description().sample_rate / options.stream_speed; }

  void BeginRecording() {
    Current& c = *current;
    const SteadyStateVerdict& v = c.detector->verdict();
    if (v.timed_out) {
      Event("not-steady", fmt::format("experiment '{}': not steady after {} cycles (last change {:.2f} x tolerance); "
                                      "recorded all the same",
                                      c.item.label(), v.cycles, v.measure));
    }
    recorder.BeginExperiment(Descriptor());
    c.open = true;
    c.recorded = 0;
    c.first_recorded_cycle = static_cast<long>(c.cycles.back().cycle) + 1;
    SetPhase(RunPhase::kRecording);
  }

  void StoreCycles(const Current& c) {
    daq::MetadataGroup g = CyclesGroup(c.item.label(), c.cycles, c.detector->verdict(), options.steady);
    g.attributes["matrix_label"] = c.item.entry.label;
    g.attributes["samples_per_cycle"] = static_cast<long long>(c.spp);
    g.attributes["first_recorded_cycle"] = static_cast<long long>(c.first_recorded_cycle);
    g.attributes["commanded_amplitude"] = c.item.entry.amplitude;
    recorder.AddMetadata({"rig_run", {}, {std::move(g)}});
  }

  void FinishRecording() {
    Current& c = *current;
    const bool steady = c.detector->verdict().steady;
    StoreCycles(c);
    recorder.EndExperiment(steady ? daq::EndStatus::kComplete : daq::EndStatus::kNotSteady, options.periods);
    c.open = false;
    c.finished = true;
    (steady ? report->complete : report->not_steady).push_back(c.item.label());
  }

  // Lost samples inside the record: the contract wants a constant rate, so this record ends aborted
  // and the experiment is recorded again under its next attempt's label once steady again.
  void AbortRecording(const std::string& why) {
    Current& c = *current;
    Event("abort", fmt::format("experiment '{}': {}; recorded aborted", c.item.label(), why));
    StoreCycles(c);
    recorder.EndExperiment(daq::EndStatus::kAborted);
    report->aborted.push_back(c.item.label());
    c.open = false;
    if (c.item.attempt >= options.max_attempts) {
      throw Interrupt{Trip{"sequence-gaps", SafetyAction::kStop, Now(),
                           fmt::format("experiment '{}': {} recordings cut by lost samples", c.item.entry.label,
                                       c.item.attempt)}};
    }
    c.item.attempt += 1;
    c.detector.emplace(options.steady);
    c.cycles.clear();
    c.first_recorded_cycle = -1;
    SetPhase(RunPhase::kSettling);
  }

  // ---- the controller

  // A command to the controller. A refusal ends the experiment at once; a lost connection or a
  // timeout is retried for controller_grace (a reconnect), then the controller is lost.
  template <typename F>
  void Call(const char* what, F&& call) {
    const std::int64_t deadline = Now() + Ns(options.controller_grace);
    for (;;) {
      try {
        call();
        return;
      } catch (const daq::DeviceError& e) {
        const bool refused =
            e.kind() == daq::DeviceError::Kind::kRefused || e.kind() == daq::DeviceError::Kind::kInvalidValue;
        if (!refused && Now() < deadline) {
          spdlog::debug("{}: {} (retrying)", what, e.what());
          std::this_thread::sleep_for(options.loop);
          continue;
        }
        if (!refused) controller_lost = true;
        throw Interrupt{Trip{refused ? "controller-refused" : "controller-lost",
                             refused ? SafetyAction::kStop : SafetyAction::kInterlock, Now(),
                             fmt::format("{}: {}", what, e.what())}};
      }
    }
  }

  daq::SetPoint SetPointFor(const MatrixEntry& e, double amplitude) const {
    daq::SetPoint s;
    s.mode = daq::ControlMode::kStroke;
    s.static_position = e.static_position;
    s.amplitude = amplitude;
    s.frequency = e.frequency;
    s.ramp_cycles = options.ramp_cycles;
    s.static_rate = options.static_rate;
    s.limits = safety.config().controller;
    return s;
  }

  //! `seconds` is what the wait should take on the recorded clock (a move, a ramp, the steady-state
  //! time limit); the stream delivers it stream_speed times faster.
  template <typename P>
  void WaitUntil(P&& done, double seconds, const std::string& what) {
    const double wall_seconds = seconds / options.stream_speed;
    const std::int64_t deadline = Now() + Seconds(wall_seconds) + Ns(options.settle_margin);
    while (!done()) {
      if (Now() > deadline) {
        const std::string text = fmt::format(
            "{} did not happen within {:.1f} s (controller {}, status {}, stroke {:.6g} m)", what,
            wall_seconds + options.settle_margin.count() * 1e-3, daq::ToString(status.state),
            daq::StatusBitsText(status.status_word), status.stroke);
        if (safing) {
          Event("safing", text);
          return;
        }
        throw Interrupt{Trip{"stuck", SafetyAction::kStop, Now(), text}};
      }
      Step();
      if (safing && (controller_lost || status.faulted())) return;
    }
  }

  bool AtStatic(double position) const {
    return have_status && status.state == daq::ControllerState::kArmed && (status.status_word & daq::status_bits::kAtStatic) &&
           std::abs(status.stroke - position) <= options.position_tolerance;
  }

  //! A hold at `position` (m) reached at `rate` (m/s): the moves of the top-out reference.
  daq::SetPoint HoldAt(double position, double rate) const {
    daq::SetPoint s;
    s.mode = daq::ControlMode::kStroke;
    s.static_position = position;
    s.amplitude = 0.0;
    s.frequency = 0.0;
    s.ramp_cycles = options.ramp_cycles;
    s.static_rate = rate;
    s.limits = safety.config().controller;
    return s;
  }

  //! The top-out reference (top_out.h): to the search's start, the slow search toward full
  //! extension until the contact shows in the force (or the search's end), back to the start, and
  //! the zero fitted to the search's samples. Every wait has its limit (the distance at its rate
  //! plus the settle margin, as the moves of an experiment); the safety detectors watch throughout.
  void TopOut(const TopOutOptions& o, std::size_t total) {
    progress = Progress{};
    progress.experiment = "top-out";
    progress.total = total;
    SetPhase(RunPhase::kReference);
    spdlog::info("top-out reference: from {:.2f} mm toward full extension at {:.3g} mm/s, down to {:.2f} mm, until "
                 "the force falls {:.0f} N below its trend",
                 o.from * 1e3, o.rate * 1e3, o.to * 1e3, o.force_drop);
    const double distance = have_status ? std::abs(status.stroke - o.from) : 0.0;
    Call("set-point (top-out reference start)", [&] { controller.WriteSetPoint(HoldAt(o.from, options.static_rate)); });
    if (status.state == daq::ControllerState::kDisarmed) Call("arm", [&] { controller.Arm(); });
    Step();
    WaitUntil([&] { return AtStatic(o.from); }, distance / options.static_rate,
              fmt::format("the move to the top-out reference's start {:.4g} m", o.from));

    reference.emplace(o);
    reference->collecting = true;
    Call("set-point (top-out search)", [&] { controller.WriteSetPoint(HoldAt(o.to, o.rate)); });
    Step();
    WaitUntil([&] { return reference->detector.found() || AtStatic(o.to); }, (o.from - o.to) / o.rate,
              fmt::format("the top-out search from {:.4g} m to {:.4g} m", o.from, o.to));
    // Every sample collected so far was taken before the move turns back.
    reference->collecting = false;
    const bool found = reference->detector.found();
    const double deepest = have_status ? status.stroke : o.to;
    Call("set-point (back from top-out)", [&] { controller.WriteSetPoint(HoldAt(o.from, options.static_rate)); });
    Step();
    WaitUntil([&] { return AtStatic(o.from); }, std::abs(deepest - o.from) / options.static_rate,
              fmt::format("the move back from top-out to {:.4g} m", o.from));

    const Reference& r = *reference;
    daq::MetadataGroup g{"top_out", {}, {}};
    g.attributes["from"] = o.from;
    g.attributes["to"] = o.to;
    g.attributes["rate"] = o.rate;
    g.attributes["force_limit"] = o.force_drop;
    g.attributes["samples"] = static_cast<long long>(r.time.size());
    if (found) {
      g.attributes["contact_stroke"] = r.detector.stroke_at_contact();
      try {
        const double resolution = std::abs(acquisition.description().channels[stroke_k].calibration.gain);
        const TopOutFit fit = FitTopOut(r.time, r.stroke, r.force, r.detector.stroke_at_contact(), resolution, o);
        report->top_out = fit;
        g.attributes["stroke_zero"] = fit.zero;
        g.attributes["stroke_zero_sd"] = fit.sd;
        g.attributes["fit_sd"] = fit.fit_sd;
        g.attributes["contact_stiffness"] = fit.stiffness;
        g.attributes["stroke_rate"] = fit.stroke_rate;
        g.attributes["residual_rms"] = fit.residual_rms;
        g.attributes["fitted_samples"] = static_cast<long long>(fit.samples);
        g.attributes["samples_in_contact"] = static_cast<long long>(fit.in_contact);
      } catch (const std::invalid_argument& e) {
        report->top_out_failure = fmt::format("the contact showed at {:.3f} mm but no zero could be fitted: {}",
                                              r.detector.stroke_at_contact() * 1e3, e.what());
      }
    } else {
      report->top_out_failure =
          fmt::format("no top-out contact between {:.2f} and {:.2f} mm: the force never fell {:.0f} N below its trend",
                      o.from * 1e3, o.to * 1e3, o.force_drop);
    }
    g.attributes["verdict"] = std::string(report->top_out ? "found" : "not found");
    recorder.AddMetadata({"rig_run", {}, {std::move(g)}});
    if (report->top_out) {
      const TopOutFit& fit = *report->top_out;
      // The /calibration group as the session format writes it (daq::RecordZeros), merged into the
      // recording so that a load-cell zero recorded beside it stays.
      daq::Session zeros;
      daq::RecordZeros({.stroke = daq::MeasuredZero{fit.zero, fit.sd}}, zeros);
      recorder.AddMetadata(zeros.metadata.back());
      Event("top-out", fmt::format("top-out reference: stroke zero {:.4f} mm, sd {:.4f} mm (contact {:.3g} N/m, {} "
                                   "samples, {} in contact)",
                                   fit.zero * 1e3, fit.sd * 1e3, fit.stiffness, fit.samples, fit.in_contact));
      spdlog::info("top-out reference: the stroke reads {:.4f} mm (sd {:.4f} mm) at full extension", fit.zero * 1e3,
                   fit.sd * 1e3);
    } else {
      Event("top-out", "top-out reference: " + report->top_out_failure +
                           "; the run goes on without a stroke zero (identify keeps its 2 mm prior on theta12)");
      spdlog::warn("top-out reference: {}; the run goes on without a stroke zero", report->top_out_failure);
    }
    reference.reset();
  }

  void RunExperiment(const RunItem& item, std::size_t index, std::size_t total) {
    const MatrixEntry& e = item.entry;
    current.emplace();
    Current& c = *current;
    c.item = item;
    c.spp = *daq::WholeSamplesPerPeriod(RecordedRate(), e.frequency, 2);
    c.wanted = c.spp * options.periods;
    progress = Progress{};
    progress.experiment = item.label();
    progress.index = index;
    progress.total = total;
    progress.periods_requested = options.periods;
    spdlog::info("experiment '{}' ({}/{}): {} Hz, amplitude {:.4g} m about {:.4g} m", item.label(), index + 1, total,
                 e.frequency, e.amplitude, e.static_position);

    SetPhase(RunPhase::kMoving);
    const double distance = have_status ? std::abs(status.stroke - e.static_position) : 0.0;
    Call("set-point (static position)", [&] { controller.WriteSetPoint(SetPointFor(e, 0.0)); });
    if (status.state == daq::ControllerState::kDisarmed) Call("arm", [&] { controller.Arm(); });
    Step();
    WaitUntil([&] { return AtStatic(e.static_position); }, distance / options.static_rate,
              fmt::format("the move to the static position {:.4g} m", e.static_position));

    SetPhase(RunPhase::kRampIn);
    Call("set-point (sine)", [&] { controller.WriteSetPoint(SetPointFor(e, e.amplitude)); });
    Call("run", [&] { controller.Run(); });
    WaitUntil(
        [&] {
          return status.state == daq::ControllerState::kRunning &&
                 (status.status_word & daq::status_bits::kFullAmplitude) != 0;
        },
        (options.ramp_cycles + 1) / e.frequency, "full amplitude after the ramp in");

    SetPhase(RunPhase::kSettling);
    c.full_amplitude_ns = Now();
    c.summariser.emplace(c.spp);
    c.detector.emplace(options.steady);
    c.summarising = true;
    WaitUntil([&] { return c.finished; },
              options.steady.time_limit + (options.periods + 2.0 * options.steady.max_cycles + 2.0) / e.frequency,
              "steady state and the record");

    SetPhase(RunPhase::kRampOut);
    Call("stop (ramp out)", [&] { controller.Stop(); });
    WaitUntil([&] { return AtStatic(e.static_position); }, (options.ramp_cycles + 1) / e.frequency,
              "the ramp out to the static position");
    current.reset();
  }

  // After an interrupt: the experiment in progress ends aborted with its cause, the controller goes
  // to the safe state the action asks for.
  void Safe(const Trip& trip) {
    safing = true;
    progress.phase = RunPhase::kSafing;
    ReportProgress(true);
    spdlog::error("{}: {} (action {})", trip.detector, trip.text, ToString(trip.action));
    Event(trip.detector == "operator-stop" ? "stop" : "trip",
          fmt::format("{}: {} (action {})", trip.detector, trip.text, ToString(trip.action)), trip.monotonic_ns);
    if (current) current->summarising = false;  // nothing more is recorded while safing
    if (reference) reference->collecting = false;
    if (current && current->open) {
      try {
        StoreCycles(*current);
        recorder.EndExperiment(daq::EndStatus::kAborted);
        report->aborted.push_back(current->item.label());
      } catch (const daq::RecorderError& e) {
        spdlog::error("{}", e.what());
      }
      current->open = false;
    }
    const double frequency = current ? current->item.entry.frequency : 1.0;
    if (controller_lost) return;  // nothing to command; the controller's watchdog stops it
    if (trip.action == SafetyAction::kInterlock || status.faulted()) {
      Disarm();
      return;
    }
    try {
      if (status.state == daq::ControllerState::kRunning) controller.Stop();
    } catch (const daq::DeviceError& e) {
      spdlog::error("stop: {}", e.what());
      Disarm();
      return;
    }
    if (status.state == daq::ControllerState::kRunning || status.state == daq::ControllerState::kStopping) {
      WaitUntil([&] { return status.state == daq::ControllerState::kArmed &&
                             (status.status_word & daq::status_bits::kAtStatic) != 0; },
                (options.ramp_cycles + 1) / frequency, "the ramp out to the static level");
    }
  }

  void Disarm() {
    if (controller_lost) return;
    try {
      controller.SetWatchdog(std::chrono::milliseconds(0));
    } catch (const daq::DeviceError& e) {
      spdlog::warn("watchdog off: {}", e.what());
    }
    try {
      controller.Disarm();
      disarmed = true;
    } catch (const daq::DeviceError& e) {
      spdlog::error("disarm: {}", e.what());
    }
  }
};

MatrixRunner::MatrixRunner(daq::ActuatorController& controller, daq::AcquisitionModule& acquisition,
                           daq::Recorder& recorder, SafetyConfig safety, RunnerOptions options) {
  std::string error;
  if (!options.IsValid(&error)) throw std::invalid_argument("runner options: " + error);
  impl_ = std::make_unique<Impl>(*this, controller, acquisition, recorder, std::move(safety), std::move(options));
  const auto& channels = acquisition.description().channels;
  for (std::size_t k = 0; k < channels.size(); ++k) {
    if (channels[k].name == "stroke") impl_->stroke_k = static_cast<int>(k);
    if (channels[k].name == "force") impl_->force_k = static_cast<int>(k);
    if (channels[k].name == "pressure") impl_->pressure_k = static_cast<int>(k);
  }
  if (impl_->stroke_k < 0 || impl_->force_k < 0)
    throw std::invalid_argument(fmt::format("{}: the acquisition streams no stroke and force channels",
                                            acquisition.description().source));
}

MatrixRunner::~MatrixRunner() = default;

RunReport MatrixRunner::Run(const std::vector<RunItem>& items) {
  Impl& m = *impl_;
  RunReport report;
  m.report = &report;
  m.safing = false;
  m.controller_lost = m.acquisition_lost = false;
  const double rate = m.RecordedRate();
  for (const RunItem& item : items) {
    if (!daq::WholeSamplesPerPeriod(rate, item.entry.frequency, 2)) {
      report.outcome = RunOutcome::kAborted;
      report.cause = fmt::format("experiment '{}': {} Hz sampled at {} Hz is no whole number of samples per period",
                                 item.label(), item.entry.frequency, rate);
      for (const RunItem& i : items) report.remaining.push_back(i.entry.label);
      m.Event("abort", report.cause);
      return report;
    }
  }
  m.progress = Progress{};
  m.progress.total = items.size();
  m.SetPhase(RunPhase::kStarting);
  std::size_t next = 0;
  try {
    try {
      m.acquisition.Start();
    } catch (const daq::DeviceError& e) {
      throw Interrupt{Trip{"acquisition-lost", SafetyAction::kStop, Now(), fmt::format("cannot start: {}", e.what())}};
    }
    m.Call("read status", [&] { m.status = m.controller.ReadStatus(); });
    m.have_status = true;
    if (m.options.reset_heartbeat_fault && m.status.fault_word == daq::fault_bits::kHeartbeatLost) {
      m.Event("reset", fmt::format("the controller latched heartbeat-lost (its watchdog fired after the previous run "
                                   "stopped beating, state {}): reset before going on",
                                   daq::ToString(m.status.state)));
      m.Call("reset faults", [&] { m.controller.ResetFaults(); });
      m.Call("read status", [&] { m.status = m.controller.ReadStatus(); });
    }
    if (m.status.faulted()) {
      throw Interrupt{Trip{"controller-fault", SafetyAction::kInterlock, Now(),
                           fmt::format("the controller has latched faults 0x{:04x} ({}) before the run: reset them first",
                                       m.status.fault_word, daq::FaultBitsText(m.status.fault_word))}};
    }
    const SafetyConfig& safety = m.safety.config();
    m.Call("set watchdog", [&] {
      m.controller.SetWatchdog(safety.heartbeat.enabled ? safety.heartbeat.watchdog : std::chrono::milliseconds(0));
    });
    m.safety.Reset(Now());
    if (m.options.top_out) m.TopOut(*m.options.top_out, items.size());
    for (; next < items.size(); ++next) {
      if (pause_.load()) {
        report.outcome = RunOutcome::kPaused;
        report.cause = fmt::format("paused at the operator's request before experiment '{}'", items[next].label());
        m.Event("pause", report.cause + fmt::format("; {} experiments remain", items.size() - next));
        break;
      }
      m.RunExperiment(items[next], next, items.size());
    }
  } catch (const Interrupt& x) {
    report.trip = x.trip;
    report.outcome = x.trip.action == SafetyAction::kHold ? RunOutcome::kPaused : RunOutcome::kAborted;
    report.cause = fmt::format("{}: {}", x.trip.detector, x.trip.text);
    m.Safe(x.trip);
  } catch (const daq::RecorderError& e) {
    report.outcome = RunOutcome::kAborted;
    report.trip = Trip{"recorder", SafetyAction::kStop, Now(), e.what()};
    report.cause = fmt::format("recorder: {}", e.what());
    m.Safe(*report.trip);
  }
  // Whatever happened: the controller disarmed (hydraulics off, watchdog off), the stream stopped.
  m.safing = true;
  if (!m.disarmed) {
    if (m.status.state == daq::ControllerState::kRunning && !m.controller_lost) {
      try {
        m.controller.Stop();
        m.WaitUntil([&] { return m.status.state != daq::ControllerState::kRunning &&
                                 m.status.state != daq::ControllerState::kStopping; },
                    5.0, "the ramp out");
      } catch (const daq::DeviceError& e) {
        spdlog::error("stop: {}", e.what());
      }
    }
    m.Disarm();
  }
  report.disarmed = m.disarmed;
  report.largest_lag = static_cast<double>(m.safety.largest_lag_ns()) * 1e-9;
  report.lag_limit = static_cast<double>(m.safety.max_lag().count()) * 1e-3;
  try {
    m.acquisition.Stop();
  } catch (const daq::DeviceError& e) {
    spdlog::warn("stopping the acquisition: {}", e.what());
  }
  for (std::size_t i = next; i < items.size(); ++i) {
    const std::string label = items[i].label();
    bool recorded = false;
    for (const auto& l : report.complete) recorded |= l == label;
    for (const auto& l : report.not_steady) recorded |= l == label;
    if (!recorded) report.remaining.push_back(items[i].entry.label);
  }
  if (report.outcome != RunOutcome::kComplete) {
    m.Event(report.outcome == RunOutcome::kPaused ? "paused" : "aborted",
            fmt::format("run {}: {}; remaining: {}", ToString(report.outcome), report.cause,
                        report.remaining.empty() ? std::string("none") : fmt::format("{}", fmt::join(report.remaining, " "))));
  } else {
    m.Event("complete", fmt::format("run complete: {} experiments recorded", items.size()));
  }
  m.progress.phase = RunPhase::kDone;
  m.ReportProgress(true);
  m.current.reset();
  m.reference.reset();
  m.report = nullptr;
  return report;
}

}  // namespace strut::rig
