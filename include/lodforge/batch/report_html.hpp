// The batch run's human-readable report: OUT_DIR/report.html, rendered from the same document as report.json
// (issue 5, "Report").
//
//   const nlohmann::json report = ...;  // the batch runner's report.json document
//   write_file(out_dir / "report.html", render_report_html(report));
//
// The page is self-contained: inline CSS, a small inline script for click-to-sort tables, and plots as inline
// SVG drawn here, so it opens from a file share or a CI artifact with no network. A Content-Security-Policy
// meta tag forbids every external load, so a stray reference would show as blocked rather than phone home.
// Sections, top to bottom:
//   - header: lodforge version, config file, jobs, shard and the summary figures;
//   - failures: path and error of every failed asset;
//   - one table row per asset x LOD, worst first: failed assets on top, then by measured Hausdorff distance
//     (relative to the source's bounding-box diagonal) descending; every column header sorts on click;
//   - per class, a scatter of measured mean error (% of diagonal, log scale) against achieved triangle ratio,
//     coloured by LOD level, and a bar chart of the ten assets with the largest Hausdorff distance;
//   - the effective config, folded.
//
// Tolerance: the document is read, never trusted. Missing fields, nulls, wrong types and non-finite numbers
// render as "–"; unknown fields are ignored; a report with no assets renders a page that says so. Every string
// from the document is HTML-escaped (invalid UTF-8 and control characters become U+FFFD), because asset paths
// and error messages are data, not markup.
//
// Determinism: the same document gives the same bytes. Nothing is added that the document does not hold (no
// render timestamp), numbers are printed with fixed precision independent of the locale, and ties in every
// ordering break by path and LOD level.
#pragma once

#include <nlohmann/json.hpp>
#include <string>

namespace lodforge::batch {

// The complete HTML5 page for a report.json document (shape: see the batch runner). Never throws on a
// well-formed JSON value, whatever its content; throws only std::bad_alloc.
std::string render_report_html(const nlohmann::json& report);

}  // namespace lodforge::batch
