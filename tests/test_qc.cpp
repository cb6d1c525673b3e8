// Production QC (docs/qc.md): the quantities against closed forms, references and their errors,
// the guard-band rule, the history in SQLite, defective units, a small lot decided on the
// simulated rig, and the golden unit's re-test (the CLI: test_qc_cli.cpp).
#include <gtest/gtest.h>
#include <sqlite3.h>

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>

#include "lot_sessions.h"
#include "strut/daq/session.h"
#include "strut/qc/decision.h"
#include "strut/qc/history.h"
#include "strut/qc/matrix.h"
#include "strut/report/fit_report.h"
#include "strut/report/qc_report.h"
#include "strut/sim/simulated_rig.h"
#include "strut/study/lot.h"
#include "test_support.h"

namespace strut::qc {
namespace {

// The lot study's units and defects (study/) are what these tests decide.
using study::Defect;
using study::Defects;
using study::LotReference;
using study::LotUnit;
using study::MakeDefective;
using study::QcMatrix;
using test::QcSession;

constexpr double kPatm = 101325.0;

const Quantity& Find(const std::vector<Quantity>& qs, const std::string& name) {
  for (const auto& q : qs)
    if (q.name == name) return q;
  throw std::runtime_error("no quantity " + name);
}

TEST(QcQuantities, MatchTheirClosedFormsOnTheTwoDofModel) {
  const ident::Model model = ident::Model::Build("2dof+viscous-damping", ident::Causality::kStrokeInput);
  ident::ParameterSet p = model.defaults();
  p.set("theta5", 2300.0);
  p.set("theta6", -3.1);
  p.set("theta7", 3e-5);
  p.set("theta12", -0.002);  // the sensor zero must not move the charge: it is the pressure at true stroke 0
  p.set("theta18", 450.0);
  const auto qs = ComputeQuantities(model, p.values());
  const double T = -p.get("theta17");
  // method.md's 2 dof gas law at q = 0: p = theta5 T / (1 + theta7 T).
  const double p0 = 2300.0 * T / (1 + 3e-5 * T);
  EXPECT_NEAR(Find(qs, "charge_pressure").value, p0, 1e-6 * p0);
  EXPECT_DOUBLE_EQ(Find(qs, "gas_column").value, 1 / 3.1);
  EXPECT_NEAR(Find(qs, "friction").value, (p.get("theta8") + p.get("theta9") * p0) * M_PI / 2, 1e-6);
  EXPECT_DOUBLE_EQ(Find(qs, "orifice_damping").value, p.get("theta3"));
  EXPECT_DOUBLE_EQ(Find(qs, "viscous_damping").value, 450.0);
  EXPECT_DOUBLE_EQ(Find(qs, "load_cell_zero").value, p.get("theta11") + kPatm * p.get("theta4"));
  EXPECT_DOUBLE_EQ(Find(qs, "stroke_offset").value, -0.002);
  // A model without the seal damping term has no such quantity.
  const ident::Model plain = ident::Model::Build("2dof", ident::Causality::kStrokeInput);
  for (const auto& q : ComputeQuantities(plain, plain.defaults().values())) EXPECT_NE(q.name, "viscous_damping");
}

TEST(QcQuantities, SdFollowsTheCovarianceByLinearisation) {
  const ident::Model model = ident::Model::Build("2dof", ident::Causality::kStrokeInput);
  ident::FitSummary fit;
  fit.parameters = model.defaults();
  const int n = fit.parameters.size();
  fit.estimates.assign(n, ident::ParameterEstimate{});
  const int i6 = fit.parameters.position("theta6"), i8 = fit.parameters.position("theta8"),
            i9 = fit.parameters.position("theta9"), i5 = fit.parameters.position("theta5");
  fit.estimated_positions = {i5, i6, i8, i9};
  for (int i : fit.estimated_positions) fit.estimates[i].estimated = true;
  fit.estimates[i5].sd = 5.0;
  fit.estimates[i6].sd = 0.02;
  fit.estimates[i8].sd = 3.0;
  fit.estimates[i9].sd = 1e-6;
  fit.correlation = Eigen::MatrixXd::Identity(4, 4);
  fit.correlation(2, 3) = fit.correlation(3, 2) = -0.5;
  const auto qs = ComputeQuantities(model, fit);
  const double t6 = fit.parameters.value(i6);
  EXPECT_NEAR(Find(qs, "gas_column").sd, 0.02 / (t6 * t6), 1e-6 * 0.02 / (t6 * t6));  // d(-1/x) = dx / x^2
  // friction = (theta8 + theta9 p0) pi/2 with p0 from theta5 (p0 is linear in theta5).
  const double p0 = Find(qs, "charge_pressure").value, dp0 = p0 / fit.parameters.value(i5);
  const double g5 = fit.parameters.value(i9) * dp0, g8 = 1, g9 = p0;
  const double var = g5 * g5 * 25 + g8 * g8 * 9 + g9 * g9 * 1e-12 + 2 * g8 * g9 * (-0.5) * 3.0 * 1e-6;
  EXPECT_NEAR(Find(qs, "friction").sd, M_PI / 2 * std::sqrt(var), 1e-4 * M_PI / 2 * std::sqrt(var));
  EXPECT_NEAR(Find(qs, "charge_pressure").sd, dp0 * 5.0, 1e-4 * dp0 * 5.0);
  EXPECT_TRUE(std::isnan(Find(qs, "orifice_damping").sd));  // theta3 was not estimated
}

TEST(QcReference, NominalFileInTomlAndJsonGiveTheSameBands) {
  const std::string toml = "model = \"2dof\"\n[charge_pressure]\nnominal = 7e5\nlower = 6.5e5\nupper = 7.5e5\n"
                           "[friction]\nnominal = 300\ntolerance = 0.5\n";
  const std::string json = R"({"model": "2dof", "quantities": {"charge_pressure": {"nominal": 7e5, "lower": 6.5e5,
      "upper": 7.5e5}, "friction": {"nominal": 300, "tolerance": 0.5}}})";
  for (const Reference& r : {ParseNominalFile(toml, "r.toml"), ParseNominalFile(json, "r.json")}) {
    EXPECT_EQ(r.model, "2dof");
    ASSERT_NE(r.find("charge_pressure"), nullptr);
    EXPECT_DOUBLE_EQ(r.find("charge_pressure")->lower, 6.5e5);
    ASSERT_NE(r.find("friction"), nullptr);
    EXPECT_DOUBLE_EQ(r.find("friction")->lower, 150);
    EXPECT_DOUBLE_EQ(r.find("friction")->upper, 450);
    EXPECT_EQ(r.find("gas_column"), nullptr);
  }
}

TEST(QcReference, MistakesNameTheFileLineAndItem) {
  const auto message = [](const std::string& text) {
    return test::ErrorOf<ReferenceError>([&] { ParseNominalFile(text, "ref.toml"); });
  };
  EXPECT_NE(message("[charge_presure]\nnominal = 1\n").find("ref.toml:1: unknown quantity 'charge_presure'"),
            std::string::npos);
  EXPECT_NE(message("\n[friction]\nlower = 1\nupper = 2\n").find("ref.toml:2: 'friction' needs a nominal"),
            std::string::npos);
  EXPECT_NE(message("[friction]\nnominal = 1\nlower = 3\nupper = 2\n").find("lower <= nominal <= upper"),
            std::string::npos);
  EXPECT_NE(message("[friction]\nnominal = \"x\"\n").find("ref.toml:2: [friction] nominal: expected a number, got the string \"x\""),
            std::string::npos);
  EXPECT_NE(message("[friction]\nnominal = 1\nlower = 0\nupper = 2\nmargin = 3\n").find("unknown key 'margin'"),
            std::string::npos);
  EXPECT_NE(message("[friction\n").find("ref.toml:1:"), std::string::npos);
  EXPECT_THROW(ReadReference("/no/such/ref.toml"), ReferenceError);
}

TEST(QcReference, AGoldenFitGivesItsQuantitiesWithTheDefaultBands) {
  const ident::Model model = ident::Model::Build("2dof", ident::Causality::kStrokeInput);
  ident::FitSummary fit;
  fit.model = "2dof";
  fit.parameters = model.defaults();
  fit.parameters.set("theta3", 9000.0);
  fit.estimates.assign(fit.parameters.size(), ident::ParameterEstimate{});
  nlohmann::json j = report::FitToJson(fit);
  j["verdict"] = "at-noise-floor";  // the summary here is made by hand, not fitted
  const Reference r = ReferenceFromFitJson(j.dump(), "golden.json");
  EXPECT_EQ(r.kind, "golden-fit");
  EXPECT_EQ(r.model, "2dof");
  const Band* orifice = r.find("orifice_damping");
  ASSERT_NE(orifice, nullptr);
  EXPECT_DOUBLE_EQ(orifice->nominal, 9000.0);
  for (const DefaultBand& d : DefaultBands())
    if (d.name == "orifice_damping") {
      EXPECT_DOUBLE_EQ(orifice->lower, 9000.0 * (1 - d.below));
      EXPECT_DOUBLE_EQ(orifice->upper, 9000.0 * (1 + d.above));
    }
  EXPECT_EQ(r.find("viscous_damping"), nullptr);  // the golden model has no such term
  EXPECT_THROW(ReferenceFromFitJson(R"({"model": "2dof"})", "g.json"), ReferenceError);
  j["verdict"] = "above-noise-floor";  // a golden unit whose fit the model does not explain is no reference
  EXPECT_THROW(ReferenceFromFitJson(j.dump(), "g.json"), ReferenceError);
  EXPECT_THROW(ReferenceFromFitJson(R"({"model": "2dof", "parameters": [{"index": "theta99", "value": 1}]})", "g.json"),
               ReferenceError);
}

Reference Bands() {
  return ParseNominalFile("[charge_pressure]\nnominal = 7e5\nlower = 6.5e5\nupper = 7.5e5\n"
                          "[friction]\nnominal = 300\nlower = 150\nupper = 450\n",
                          "bands.toml");
}

TEST(QcDecision, TheGuardBandDecidesAnIntervalThatStraddlesALimit) {
  const Reference r = Bands();
  const Band* b = r.find("charge_pressure");
  const auto q = [](double v, double sd) { return Quantity{"charge_pressure", "Pa", "", v, sd}; };
  EXPECT_EQ(DecideQuantity(q(7.0e5, 1e3), b).status, Status::kIn);
  EXPECT_EQ(DecideQuantity(q(6.37e5, 1e3), b).status, Status::kOut);
  // Inside the band but within 1.96 sd of the limit: not shown to conform.
  const QuantityDecision g = DecideQuantity(q(6.51e5, 1e3), b);
  EXPECT_EQ(g.status, Status::kGuardBand);
  EXPECT_NE(g.meaning.find("straddles the lower limit"), std::string::npos) << g.meaning;
  // Outside, but within 1.96 sd: not shown out either; the rule decides it as out too.
  EXPECT_EQ(DecideQuantity(q(6.49e5, 1e3), b).status, Status::kGuardBand);
  EXPECT_EQ(DecideQuantity(q(7.0e5, 3e4), b).status, Status::kUndetermined);  // interval wider than the band
  EXPECT_EQ(DecideQuantity(q(7.0e5, NAN), b).status, Status::kUndetermined);
  EXPECT_EQ(DecideQuantity(q(7.0e5, 1e3), nullptr).status, Status::kUntoleranced);
  // Physical meaning of the failures.
  EXPECT_NE(DecideQuantity(q(6.37e5, 1e3), b).meaning.find("gas under-charged by 9 %"), std::string::npos);
  const QuantityDecision f = DecideQuantity({"friction", "N", "", 600.0, 5.0}, r.find("friction"));
  EXPECT_NE(f.meaning.find("seal friction 2.0 times nominal"), std::string::npos) << f.meaning;
}

TEST(QcDecision, VerdictNeverPassesAFitItCannotTrust) {
  const Reference r = Bands();
  const std::vector<Quantity> good = {{"charge_pressure", "Pa", "", 7.0e5, 1e3}, {"friction", "N", "", 300, 5}};
  EXPECT_EQ(Decide(good, r, ident::FitVerdict::kAtNoiseFloor, {}).verdict, Verdict::kPass);
  const Decision above = Decide(good, r, ident::FitVerdict::kAboveNoiseFloor, {});
  EXPECT_EQ(above.verdict, Verdict::kUndecided);
  EXPECT_NE(above.reasons.front().find("above the noise floor"), std::string::npos);
  EXPECT_EQ(Decide(good, r, ident::FitVerdict::kNotConverged, {}).verdict, Verdict::kUndecided);
  EXPECT_EQ(Decide(good, r, ident::FitVerdict::kAtNoiseFloor, {{"q1", "force", "dropout", "12 samples"}}).verdict,
            Verdict::kUndecided);
  std::vector<Quantity> bad = good;
  bad[1].value = 600;
  const Decision fail = Decide(bad, r, ident::FitVerdict::kAtNoiseFloor, {});
  EXPECT_EQ(fail.verdict, Verdict::kFail);
  ASSERT_EQ(fail.reasons.size(), 1u);
  EXPECT_EQ(fail.reasons[0].rfind("friction: seal friction 2.0 times nominal", 0), 0u) << fail.reasons[0];
  // A band for a quantity the fit lacks cannot be decided.
  EXPECT_EQ(Decide({good[0]}, r, ident::FitVerdict::kAtNoiseFloor, {}).verdict, Verdict::kUndecided);
  EXPECT_EQ(ExitCodeOf(Verdict::kPass), 0);
  EXPECT_EQ(ExitCodeOf(Verdict::kFail), 1);
  EXPECT_EQ(ExitCodeOf(Verdict::kUndecided), 2);
  const nlohmann::json j = report::QcToJson(fail);
  EXPECT_EQ(j["verdict"], "FAIL");
  for (const char* key : {"name", "value", "sd", "nominal", "lower", "upper", "status", "meaning"})
    EXPECT_TRUE(j["quantities"][1].contains(key)) << key;
  EXPECT_EQ(j["quantities"][1]["status"], "out");
}

TEST(QcHistory, StoresEveryDecisionAndQueriesBySerialDateAndTrend) {
  test::TempDir dir;
  const Reference r = Bands();
  {
    History h(dir.file("qc.db"));
    for (int day = 1; day <= 3; ++day) {
      Decision d = Decide({{"charge_pressure", "Pa", "", 7.0e5 - 1e4 * day, 1e3}, {"friction", "N", "", 300, 5}}, r,
                          ident::FitVerdict::kAtNoiseFloor, {});
      d.serial = "SN-1";
      h.Record(d, "2026-11-0" + std::to_string(day) + "T08:00:00Z");
    }
    Decision other = Decide({{"charge_pressure", "Pa", "", 6.0e5, 1e3}, {"friction", "N", "", 300, 5}}, r,
                            ident::FitVerdict::kAtNoiseFloor, {});
    other.serial = "SN-2";
    h.Record(other, "2026-11-02T09:00:00Z");
  }
  History h(dir.file("qc.db"));  // reopened: the decisions persisted
  EXPECT_EQ(h.Query().size(), 4u);
  const auto sn1 = h.Query(std::string("SN-1"));
  ASSERT_EQ(sn1.size(), 3u);
  EXPECT_EQ(sn1[0].time, "2026-11-01T08:00:00Z");
  EXPECT_EQ(sn1[2].quantities.size(), 2u);
  EXPECT_DOUBLE_EQ(sn1[2].quantities[0].quantity.value, 6.7e5);
  EXPECT_EQ(h.Query(std::nullopt, std::string("2026-11-02")).size(), 3u);
  const auto sn2 = h.Query(std::string("SN-2"));
  ASSERT_EQ(sn2.size(), 1u);
  EXPECT_EQ(sn2[0].verdict, "FAIL");
  EXPECT_NE(sn2[0].reasons[0].find("under-charged"), std::string::npos);
  const auto trends = Trends(sn1);
  ASSERT_EQ(trends[0].name, "charge_pressure");
  EXPECT_NEAR(trends[0].slope_per_day, -1e4, 1e-6);  // 10 kPa lost a day: a slow leak
  EXPECT_DOUBLE_EQ(trends[0].mean, 6.8e5);
  EXPECT_THROW(h.Query(std::nullopt, std::string("yesterday")), std::invalid_argument);
  EXPECT_THROW(h.Record(Decision{}, "noon"), std::invalid_argument);
  EXPECT_EQ(h.Query().size(), 4u);  // nothing written
  {
    std::ofstream(dir.file("not.db")) << "this is no database, but it is long enough to be read as a header......\n";
  }
  try {
    History bad(dir.file("not.db"));
    FAIL() << "opened a text file as a history";
  } catch (const HistoryError& e) {
    EXPECT_NE(std::string(e.what()).find("not.db"), std::string::npos);
  }
}

TEST(QcLot, GoodUnitsLieInsideTheLotBandsAndEachDefectBeyondItsLimit) {
  const Reference r = LotReference();
  for (std::uint64_t seed = 100; seed < 112; ++seed) {
    const sim::Truth unit = LotUnit(seed);
    const ident::Model model = unit.BuildModel(ident::Causality::kStrokeInput);
    for (const Quantity& q : ComputeQuantities(model, unit.Parameters(model).values()))
      if (const Band* b = r.find(q.name)) {
        EXPECT_GT(q.value, b->lower) << q.name << " seed " << seed;
        EXPECT_LT(q.value, b->upper) << q.name << " seed " << seed;
      }
    for (Defect d : Defects()) {
      const sim::Truth bad = MakeDefective(unit, d, r, seed);
      const auto qs = ComputeQuantities(model, bad.Parameters(model).values());
      const auto v = [&](const char* n) { return Find(qs, n).value; };
      switch (d) {
        case Defect::kUnderCharge: EXPECT_LT(v("charge_pressure"), r.find("charge_pressure")->lower); break;
        case Defect::kExcessFriction: EXPECT_GT(v("friction"), r.find("friction")->upper); break;
        case Defect::kOilOverfill: EXPECT_LT(v("gas_column"), r.find("gas_column")->lower); break;
        case Defect::kLowOil: EXPECT_GT(v("gas_column"), r.find("gas_column")->upper); break;
        case Defect::kHighOrifice: EXPECT_GT(v("orifice_damping"), r.find("orifice_damping")->upper); break;
        case Defect::kLeakingSeal:
          EXPECT_GT(v("viscous_damping"), r.find("viscous_damping")->upper);
          EXPECT_LT(v("charge_pressure"), r.find("charge_pressure")->lower);
          break;
        case Defect::kNone: break;
      }
    }
  }
}

//! The small lot: two units of each kind (the seeds differ by kind, so 14 different units).
class QcSmallLot : public ::testing::TestWithParam<Defect> {};

TEST_P(QcSmallLot, GoodUnitsPassAndEachDefectFailsNamingItsQuantity) {
  const Defect kind = GetParam();
  const Reference r = LotReference();
  for (std::uint64_t k = 0; k < 2; ++k) {
    const std::uint64_t seed = 700 + 10 * static_cast<int>(kind) + k;
    const Decision d = RunQc(QcSession(seed, kind, seed), "unit", r);
    if (kind == Defect::kNone) {
      EXPECT_EQ(d.verdict, Verdict::kPass) << seed << "\n" << Table(d);
      continue;
    }
    EXPECT_EQ(d.verdict, Verdict::kFail) << ToString(kind) << " " << seed << "\n" << Table(d);
    const char* expected = kind == Defect::kUnderCharge      ? "charge_pressure"
                           : kind == Defect::kExcessFriction ? "friction"
                           : kind == Defect::kHighOrifice    ? "orifice_damping"
                           : kind == Defect::kLeakingSeal    ? "viscous_damping"
                                                             : "gas_column";
    bool named = false;
    for (const auto& q : d.quantities)
      named = named || (q.quantity.name == expected && (q.status == Status::kOut || q.status == Status::kGuardBand));
    EXPECT_TRUE(named) << ToString(kind) << " " << seed << "\n" << Table(d);
  }
}

INSTANTIATE_TEST_SUITE_P(EveryKind, QcSmallLot,
                         ::testing::Values(Defect::kNone, Defect::kUnderCharge, Defect::kExcessFriction,
                                           Defect::kOilOverfill, Defect::kLowOil, Defect::kHighOrifice,
                                           Defect::kLeakingSeal),
                         [](const auto& info) {
                           std::string n = study::ToString(info.param);
                           for (char& c : n)
                             if (c == '-') c = '_';
                           return n;
                         });

TEST(QcGolden, ARetestOfTheGoldenUnitPassesAgainstItsOwnFit) {
  // The golden unit's identify JSON from one QC session; a re-test is the same unit, new noise.
  ident::SessionFit golden;
  const Decision first = RunQc(QcSession(4242, Defect::kNone, 1), "golden", LotReference(), &golden);
  ASSERT_EQ(first.fit_verdict, "at-noise-floor");
  nlohmann::json j = report::FitToJson(golden.summary);
  const Reference ref = ReferenceFromFitJson(j.dump(), "golden.json");
  EXPECT_EQ(ref.model, kDefaultQcModel);
  const Decision again = RunQc(QcSession(4242, Defect::kNone, 2), "re-test", ref);
  EXPECT_EQ(again.verdict, Verdict::kPass) << Table(again);
  // A different unit of the lot is not the golden one: its charge or friction lies outside the
  // golden unit's tight default bands.
  const Decision other = RunQc(QcSession(4243, Defect::kNone, 3), "other", ref);
  EXPECT_EQ(other.verdict, Verdict::kFail) << Table(other);
}

}  // namespace
}  // namespace strut::qc

namespace strut::qc {
namespace {

//! A history of the first schema (version 1: no strut_schema, no keys), written by Python's
//! sqlite3 module, as the first strut left it: one decision with two quantities.
void WriteVersionOneHistory(const test::TempDir& dir, const std::string& file, const std::string& extra_sql = "") {
  const std::string script = R"(
import sqlite3, sys
db = sqlite3.connect(sys.argv[1])
db.executescript('''
CREATE TABLE decisions (id INTEGER PRIMARY KEY, serial TEXT NOT NULL, time TEXT NOT NULL, session TEXT,
  reference TEXT, model TEXT, verdict TEXT NOT NULL, reasons TEXT);
CREATE TABLE quantities (decision INTEGER NOT NULL REFERENCES decisions(id), name TEXT NOT NULL, unit TEXT,
  value REAL, sd REAL, nominal REAL, lower REAL, upper REAL, status TEXT, meaning TEXT);
INSERT INTO decisions VALUES (1, 'OLD-1', '2026-10-01T08:00:00Z', 's.h5', 'ref.toml', '2dof', 'PASS', '[]');
INSERT INTO quantities VALUES (1, 'friction', 'N', 301.5, 2.0, 300, 250, 350, 'in', '');
INSERT INTO quantities VALUES (1, 'charge_pressure', 'Pa', 7.01e5, 1e3, 7e5, 6.5e5, 7.5e5, 'in', '');
''' + sys.argv[2])
db.commit()
)";
  std::ofstream(dir.file("v1.py")) << script;
  const test::ShellResult r = test::Shell("python3 " + dir.file("v1.py") + " " + file + " \"" + extra_sql + "\"",
                                          dir.file("v1"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
}

TEST(QcHistory, MigratesTheFirstSchemaAndRefusesANewerOne) {
  test::TempDir dir;
  WriteVersionOneHistory(dir, dir.file("old.db"));
  {
    History h(dir.file("old.db"));
    EXPECT_EQ(h.schema_version(), kHistorySchemaVersion);
    const auto old = h.Query();
    ASSERT_EQ(old.size(), 1u);
    EXPECT_EQ(old[0].key, "legacy:1");
    ASSERT_EQ(old[0].quantities.size(), 2u);
    EXPECT_EQ(old[0].quantities[0].quantity.name, "friction");  // the order they were stored in
    EXPECT_EQ(old[0].quantities[1].quantity.value, 7.01e5);
    Decision d;
    d.serial = "NEW-1";
    d.quantities = {{{"friction", "N", "", 299.0, 2.0}, 300, 250, 350, Status::kIn, ""}};
    const Recorded first = h.Record(d, "2026-11-01T08:00:00Z", "key-a");
    EXPECT_TRUE(first.inserted);
    const Recorded again = h.Record(d, "2026-11-01T09:00:00Z", "key-a");  // the same key: stored once
    EXPECT_FALSE(again.inserted);
    EXPECT_EQ(again.id, first.id);
    EXPECT_NE(h.Record(d).id, first.id);  // no key: a random one of its own
  }
  History reopened(dir.file("old.db"));
  EXPECT_EQ(reopened.Query().size(), 3u);

  WriteVersionOneHistory(dir, dir.file("newer.db"),
                         "CREATE TABLE strut_schema (version INTEGER NOT NULL); INSERT INTO strut_schema VALUES (3);");
  const std::string error = test::ErrorOf<HistoryError>([&] { History h(dir.file("newer.db")); });
  EXPECT_NE(error.find("schema version 3, newer than this strut's 2"), std::string::npos) << error;
}

TEST(QcHistory, PasswordsNeverLeaveTheUrl) {
  EXPECT_EQ(RedactedLocation("postgresql://qc:s3cret@db.plant:5433/line4"), "postgresql://qc@db.plant:5433/line4");
  EXPECT_EQ(RedactedLocation("postgres://db/qc?password=s3cret&sslmode=require"), "postgres://db/qc?sslmode=require");
  EXPECT_EQ(RedactedLocation("postgresql://db/qc?sslmode=require&password=s3cret"), "postgresql://db/qc?sslmode=require");
  EXPECT_EQ(RedactedLocation("postgresql://qc@db/qc"), "postgresql://qc@db/qc");
  EXPECT_EQ(RedactedLocation("qc.db"), "qc.db");
  const std::string error = test::ErrorOf<HistoryError>([] { History h("postgresql://qc:s3cret@127.0.0.1:1/qc"); });
  EXPECT_NE(error.find("holds a password"), std::string::npos) << error;
  EXPECT_EQ(error.find("s3cret"), std::string::npos) << error;
}

}  // namespace
}  // namespace strut::qc
