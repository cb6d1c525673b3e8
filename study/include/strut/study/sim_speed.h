// The simulated rig's throughput (`strut bench sim`): the whole standard matrix with settling and
// every effect of the truth on, then a 30 s drop test, single-threaded.
#pragma once

#include <string>
#include <vector>

#include "strut/sim/simulated_rig.h"

namespace strut::study {

struct SimSpeedStudy {
  std::string composition;  //!< of the rig's model
  std::vector<sim::PeriodicRunReport> experiments;
  double matrix_wall = 0.0;  //!< s for the whole matrix
  double simulated = 0.0;    //!< simulated s of the matrix
  sim::DropSpec drop;
  sim::DropRunReport drop_report;
  double drop_wall = 0.0;
};

SimSpeedStudy MeasureSimSpeed(const sim::Truth& truth);

}  // namespace strut::study
