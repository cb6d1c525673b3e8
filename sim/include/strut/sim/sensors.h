// Sensors and acquisition of the simulated rig: each channel reads
//   reading = ADC( (1 + gain_error) * physical + offset + noise )
// with white Gaussian noise and an n-bit converter over a configured range (readings outside the
// range saturate at its ends), plus optional faults to inject: dropout, stuck value, spikes and a
// disconnected channel. docs/simulated-rig.md describes the defaults and the fault semantics.
#pragma once

#include <random>
#include <span>
#include <string>
#include <vector>

namespace strut::sim {

//! One transducer and its converter channel.
struct SensorOptions {
  std::string units;           //!< SI unit of the reading
  double range_min = -1.0;     //!< lower end of the ADC range, in units
  double range_max = 1.0;      //!< upper end of the ADC range, in units
  double noise = 0.0;          //!< white noise, rms, in units
  double offset = 0.0;         //!< zero error, in units
  double gain_error = 0.0;     //!< relative scale error (0.002 reads 0.2 % high)
  int bits = 16;               //!< ADC resolution; 0 = no quantisation and no saturation
  bool IsValid(std::string* error) const;
  double lsb() const;          //!< size of one ADC count, in units (0 when bits = 0)
};

//! The three channels of the rig (stroke: LVDT; force: load cell; pressure: gauge transducer).
struct SensorSet {
  SensorOptions stroke{"m", -0.010, 0.300, 3e-5, 0.0, 0.0, 16};
  SensorOptions force{"N", -60e3, 60e3, 20.0, 0.0, 0.0, 16};
  SensorOptions pressure{"Pa", -0.1e6, 20e6, 2.0e3, 0.0, 0.0, 16};
  bool IsValid(std::string* error) const;
};

enum class FaultKind {
  kDropout,       //!< the transducer signal drops out: the reading is the zero error plus noise
  kStuck,         //!< the reading holds the value it had when the fault began
  kSpikes,        //!< isolated samples jump by +-amplitude (fraction of the range)
  kDisconnected,  //!< the input floats to the lower rail: the lowest ADC code throughout
};
std::string_view ToString(FaultKind kind);
//! "dropout", "stuck", "spikes", "disconnected"; std::invalid_argument otherwise.
FaultKind ParseFaultKind(std::string_view text);

//! A fault injected into one channel of one experiment (or all).
struct FaultSpec {
  std::string experiment = "*";  //!< experiment label, "*" for every experiment
  std::string channel;           //!< "stroke", "force" or "pressure"
  FaultKind kind = FaultKind::kDropout;
  double start = 0.0;            //!< s from the first recorded sample
  double duration = 0.0;         //!< s; 0 means to the end of the record
  double rate = 1.0;             //!< spikes: expected spikes per second
  double amplitude = 0.1;        //!< spikes: size as a fraction of the ADC range
  bool IsValid(std::string* error) const;
  bool Applies(std::string_view label, std::string_view channel_name) const;
};

//! Converts physical values into readings: calibration errors, noise, faults, ADC. Keeps what a
//! stuck fault holds between blocks; Reset() before a new experiment.
class SensorChannel {
 public:
  //! Throws std::invalid_argument when the options are not valid.
  explicit SensorChannel(SensorOptions options);
  const SensorOptions& options() const { return options_; }

  //! Readings for a block of `physical` samples taken at `sample_rate` from record time
  //! `start_time` (s, 0 at the first recorded sample; settling samples have negative times);
  //! `faults` are those that apply to this channel and experiment.
  std::vector<double> Acquire(std::span<const double> physical, double sample_rate, double start_time,
                              std::span<const FaultSpec> faults, std::mt19937_64& rng);
  void Reset() { stuck_.clear(); }

  //! The ADC alone: nearest code, saturated to the range (identity when bits = 0).
  double Quantise(double value) const;

 private:
  SensorOptions options_;
  std::vector<std::pair<double, double>> stuck_;  //!< (start, held value) of each stuck fault begun
};

}  // namespace strut::sim
