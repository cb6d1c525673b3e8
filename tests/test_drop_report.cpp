// The drop prediction's table, JSON and HTML report (report/drop_report.h) on a prediction and a
// measured drop written here: the reports' units in the table (mm, kN, MPa, s), the relative
// errors and the inside-the-interval flags against values worked out by hand, null for what is
// not defined, and the report's plots in the same units.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "strut/report/drop_report.h"
#include "test_support.h"

namespace strut::report {
namespace {

sim::DropFigures Figures(double peak_force, double max_stroke, double peak_pressure) {
  sim::DropFigures f;
  f.peak_force = peak_force;
  f.time_of_peak_force = 0.0626;
  f.max_stroke = max_stroke;
  f.time_of_max_stroke = 0.25;
  f.rebound = 0.002;
  f.peak_pressure = peak_pressure;
  f.final_stroke = 0.2;
  return f;  // time_to_final, static_stroke, time_to_static NaN
}

DropComparison Comparison() {
  DropComparison d;
  d.fit_path = "fit.json";
  d.model = "2dof";
  d.fit_verdict = "at-noise-floor";
  d.mass = 350;
  d.impact_velocity = 0.5;
  d.options.duration = 3.0;
  d.prediction.predicted.figures = Figures(4000.0, 0.25, 12.5e6);
  // An interval on peak_force only: 3900 .. 4100 N.
  d.prediction.predicted.uncertainty.assign(sim::DropFigureNames().size(), sim::FigureUncertainty{});
  d.prediction.predicted.uncertainty[0] = {50.0, 3900.0, 4100.0};
  d.prediction.predicted.trace.time = {0.0, 0.5, 1.0};
  d.prediction.predicted.trace.stroke = {0.0, 0.25, 0.2};
  d.prediction.predicted.trace.force = {0.0, 4000.0, 3430.0};
  d.prediction.predicted.trace.pressure = {2e6, 12.5e6, 10e6};
  return d;
}

TEST(DropReport, TheTableIsInTheReportsUnits) {
  DropComparison d = Comparison();
  const DropTable t = DropFigureTable(d);
  EXPECT_EQ(t.header, (std::vector<std::string>{"figure", "predicted", "95 % interval"}));
  ASSERT_EQ(t.rows.size(), sim::DropFigureNames().size());
  const auto row = [&](const std::string& figure) {
    for (const auto& r : t.rows)
      if (r[0] == figure) return r;
    return std::vector<std::string>{};
  };
  EXPECT_EQ(row("peak_force"), (std::vector<std::string>{"peak_force", "4.000 kN", "3.900 kN .. 4.100 kN"}));
  EXPECT_EQ(row("max_stroke")[1], "250.00 mm");
  EXPECT_EQ(row("peak_pressure")[1], "12.5000 MPa");
  EXPECT_EQ(row("time_of_peak_force")[1], "0.063 s");
  EXPECT_EQ(row("time_to_static"), (std::vector<std::string>{"time_to_static", "-", "-"}));

  // Scaled and measured: the unscaled fit and the measured figure with the error beside them.
  d.prediction.unscaled = d.prediction.predicted;
  d.prediction.unscaled->figures.peak_force = 3000.0;
  d.measured = sim::MeasuredDrop{{}, Figures(3200.0, 0.25, NAN)};
  const DropTable m = DropFigureTable(d);
  EXPECT_EQ(m.header, (std::vector<std::string>{"figure", "predicted", "95 % interval", "fit unscaled", "measured",
                                                "error"}));
  EXPECT_EQ(m.rows[0], (std::vector<std::string>{"peak_force", "4.000 kN", "3.900 kN .. 4.100 kN", "3.000 kN",
                                                 "3.200 kN", "+25.0 %"}));
}

TEST(DropReport, TheJsonHasTheFiguresInSiWithErrorsAndNulls) {
  DropComparison d = Comparison();
  d.scale["theta3"] = 2.0;
  d.measured = sim::MeasuredDrop{{}, Figures(4050.0, 0.24, NAN)};
  d.measured_session = "d.h5";
  d.measured_experiment = "drop";
  const nlohmann::json j = DropJson(d);
  EXPECT_EQ(j["model"], "2dof");
  EXPECT_DOUBLE_EQ(j["scale"]["theta3"].get<double>(), 2.0);
  EXPECT_DOUBLE_EQ(j["predicted"]["peak_force"].get<double>(), 4000.0);
  EXPECT_TRUE(j["predicted"]["time_to_static"].is_null());
  EXPECT_DOUBLE_EQ(j["predicted"]["intervals"]["peak_force"]["lower"].get<double>(), 3900.0);
  EXPECT_TRUE(j["predicted"]["intervals"]["max_stroke"]["sd"].is_null());
  EXPECT_FALSE(j.contains("fitted"));
  EXPECT_EQ(j["measured"]["experiment"], "drop");
  EXPECT_NEAR(j["relative_error"]["peak_force"].get<double>(), (4000.0 - 4050.0) / 4050.0, 1e-15);
  EXPECT_NEAR(j["relative_error"]["max_stroke"].get<double>(), 0.01 / 0.24, 1e-15);
  EXPECT_TRUE(j["relative_error"]["peak_pressure"].is_null());  // nothing measured
  EXPECT_EQ(j["measured_inside_interval"], nlohmann::json({{"peak_force", true}}));
  EXPECT_TRUE(j["missing_physics"].empty());
}

TEST(DropReport, TheReportPlotsInTheSameUnits) {
  const test::TempDir dir;
  WriteDropReport(Comparison(), dir.file("drop.html"));
  const std::string html = test::ReadFile(dir.file("drop.html"));
  for (const char* text : {"Axle force, impact", "force [kN]", "stroke [mm]", "absolute pressure [MPa]",
                           "time from contact [s]", "4.000 kN"})
    EXPECT_NE(html.find(text), std::string::npos) << text;
  EXPECT_EQ(html.find("bar)"), std::string::npos);
}

}  // namespace
}  // namespace strut::report
