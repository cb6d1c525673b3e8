// Self-contained HTML reports (docs/reports.md): one file with headings, text, tables and
// interactive plotly.js figures. The plotly.js bundle is embedded in the strut binary and written
// inline into every report, so a report opens offline and refers to no other file or URL.
#pragma once

#include <Eigen/Dense>
#include <nlohmann/json.hpp>
#include <string>
#include <string_view>
#include <vector>

namespace strut::ident {

//! Crash-safe file replacement: writes and fsyncs `path`.partial, then renames it over `path`.
//! Throws std::runtime_error naming the path and the failed step.
void WriteFileAtomically(const std::string& path, std::string_view bytes);

//! One line or scatter trace of a line plot.
struct Series {
  std::string name;          //!< legend entry
  std::vector<double> x;     //!< abscissae; empty means 0, 1, 2, ... (one per y)
  std::vector<double> y;     //!< ordinates; NaN and Inf become gaps
  std::string mode = "lines";  //!< plotly scatter mode: lines, markers, lines+markers
};

//! One group of error bars: a mean and a standard deviation per category.
struct ErrorBarSeries {
  std::string name;           //!< legend entry
  std::vector<double> mean;   //!< one per category
  std::vector<double> sigma;  //!< one per category; the bars span mean +- sigma_multiple * sigma
};

//! Builds one HTML document block by block; Render() or Write() produce it.
//! Text is HTML-escaped; plots are plotly.js figures given as JSON, rendered by the browser.
class HtmlReport {
 public:
  //! The title heads the document (and names the browser tab); the generation time is taken now.
  explicit HtmlReport(std::string title);

  //! A section heading; level is clamped to 1..6 (the title is the only level 1 by convention).
  void AddHeading(const std::string& text, int level = 2);
  //! A paragraph of plain text (escaped; newlines are kept as line breaks).
  void AddParagraph(const std::string& text);
  //! A table of plain-text cells (escaped); numeric cells are right-aligned.
  //! Throws std::invalid_argument when a row has a different number of cells than the header.
  void AddTable(const std::vector<std::string>& header, const std::vector<std::vector<std::string>>& rows,
                const std::string& caption = "");
  //! A plotly figure: `traces` is the data array, `layout` is merged over the report's defaults.
  //! Non-finite numbers are written as null. Throws std::invalid_argument unless traces is an array.
  void AddPlot(const nlohmann::json& traces, const nlohmann::json& layout, const std::string& caption = "");

  //! Lines (or markers) of y over x. Throws std::invalid_argument when x and y sizes differ.
  void AddLinePlot(const std::string& title, const std::string& x_label, const std::string& y_label,
                   const std::vector<Series>& series);
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

  //! The whole HTML document, plotly.js inline.
  std::string Render() const;
  //! Writes Render() to `path` crash-safely (path.partial, fsync, rename).
  //! Throws std::runtime_error naming the path and the reason.
  void Write(const std::string& path) const;

  //! The embedded plotly.js bundle, as written into every report.
  static std::string_view PlotlyBundle();

 private:
  std::string title_;
  std::string generated_;  //!< local time of construction, ISO 8601
  std::string body_;       //!< rendered blocks
  int plots_ = 0;
};

}  // namespace strut::ident
