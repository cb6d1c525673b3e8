// Self-contained HTML reports (docs/reports.md): one file with headings, text, tables and
// interactive figures drawn by uPlot. uPlot and strut's figure code are embedded in the strut
// binary and written inline into every report, so a report opens offline and refers to no other
// file or URL.
#pragma once

#include <Eigen/Dense>
#include <nlohmann/json.hpp>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

namespace strut::report {

//! One line or scatter trace of a line plot.
struct Series {
  std::string name;          //!< legend entry
  std::vector<double> x;     //!< abscissae; empty means 0, 1, 2, ... (one per y)
  std::vector<double> y;     //!< ordinates; NaN and Inf become gaps
  std::string mode = "lines";  //!< lines, markers (small, translucent, drawn under the lines) or lines+markers
};

//! One line plot; AddLinePlots places several side by side.
struct LinePlot {
  std::string title;
  std::string x_label, y_label;
  std::vector<Series> series;
};

//! How a call-out paragraph is coloured: a verdict that is good news, a caution, a failure.
enum class Tone { kGood, kWarning, kBad };

//! One group of error bars: a mean and a standard deviation per category.
struct ErrorBarSeries {
  std::string name;           //!< legend entry
  std::vector<double> mean;   //!< one per category
  std::vector<double> sigma;  //!< one per category; the bars span mean +- sigma_multiple * sigma
};

//! Builds one HTML document block by block; Render() or Write() produce it.
//! Text is HTML-escaped; plots are figure specs (JSON) that the embedded script draws in the
//! browser. Number arrays are written once per report however many plots use them, rounded to
//! 1e-5 of their range; a series longer than kMaxPlotPoints is thinned to its envelope.
class HtmlReport {
 public:
  //! The title heads the document (and names the browser tab); the generation time is taken now.
  explicit HtmlReport(std::string title);

  //! A section heading; level is clamped to 1..6 (the title is the only level 1 by convention).
  void AddHeading(const std::string& text, int level = 2);
  //! A paragraph of plain text (escaped; newlines are kept as line breaks).
  void AddParagraph(const std::string& text);
  //! A paragraph set off by a coloured bar and background (a verdict, a warning).
  void AddCallout(const std::string& text, Tone tone);
  //! A table of plain-text cells (escaped); numeric cells are right-aligned.
  //! Throws std::invalid_argument when a row has a different number of cells than the header.
  void AddTable(const std::vector<std::string>& header, const std::vector<std::vector<std::string>>& rows,
                const std::string& caption = "");
  //! Lines (or markers) of y over x; non-finite y leave gaps. Throws std::invalid_argument when
  //! x and y sizes differ.
  void AddLinePlot(const std::string& title, const std::string& x_label, const std::string& y_label,
                   const std::vector<Series>& series);
  //! Several line plots side by side in one row (e.g. an overlay and its residual), one caption
  //! under the row. Throws std::invalid_argument as AddLinePlot; nothing is added then.
  void AddLinePlots(const std::vector<LinePlot>& row, const std::string& caption = "");
  //! A labelled square matrix (e.g. correlations) as a heat map with colour range [zmin, zmax];
  //! cells are annotated with their values up to 20 x 20. Throws std::invalid_argument unless
  //! values is labels.size() square and zmin < zmax.
  void AddHeatmap(const std::string& title, const std::vector<std::string>& labels, const Eigen::MatrixXd& values,
                  double zmin, double zmax);
  //! Per category a marker at the mean with bars of +- sigma_multiple sigma (paper Figs. 8, 11:
  //! residual mean per experiment with 2-sigma bars); several series are drawn side by side.
  //! Throws std::invalid_argument when a series does not have one mean and sigma per category.
  void AddErrorBars(const std::string& title, const std::string& y_label, const std::vector<std::string>& categories,
                    const std::vector<ErrorBarSeries>& series, double sigma_multiple = 2.0);

  //! The whole HTML document, the plotting script inline.
  std::string Render() const;
  //! Writes Render() to `path` crash-safely (daq::WriteFileAtomically). Throws
  //! daq::FileWriteError naming the path and the failed step.
  void Write(const std::string& path) const;

  //! The embedded plotting script (uPlot with its licence banner, then strut's figure code), as
  //! written into every report.
  static std::string_view PlotScript();
  //! uPlot's style sheet, as written into every report.
  static std::string_view PlotStyle();

  //! Points above which a series is thinned to the first, lowest, highest and last point of each
  //! of kMaxPlotPoints / 4 runs of consecutive points (the envelope a line plot shows).
  static constexpr std::size_t kMaxPlotPoints = 4000;

 private:
  //! Adds a figure spec; returns the <figure> markup that holds it.
  std::string Figure(nlohmann::json spec, int height, const std::string& caption);
  //! Index of `values` in the report's shared number arrays (added when new).
  int Numbers(const std::vector<double>& values);

  std::string title_;
  std::string generated_;  //!< local time of construction, ISO 8601
  std::string body_;       //!< rendered blocks
  std::vector<std::string> figures_;  //!< figure specs, JSON
  std::vector<std::string> arrays_;   //!< shared number arrays, JSON
  std::unordered_map<std::string, int> array_index_;
};

//! The plotting script every report writes inline (uPlot, then strut's figure code) and uPlot's
//! style sheet: for pages served live (monitor/), which embed uPlot the same way.
std::string_view PlotScript();
std::string_view PlotStyle();

}  // namespace strut::report
