// The batch run's human-readable report: OUT_DIR/report.html, rendered from the same document as report.json.
//
//   const nlohmann::json report = ...;  // the batch runner's report.json document
//   write_file(out_dir / "report.html", render_report_html(report));
//
// The page is self-contained: inline CSS and script, no network (a Content-Security-Policy meta tag forbids every
// external load but the LOD pictures beside it, so a stray reference would show as blocked rather than phone
// home). It is sized for libraries
// of 100 000 assets: the table is not markup but compact columnar JSON in a <script type="application/json">
// block (about 250 bytes per asset), drawn by the page 50 rows at a time. Sections, top to bottom:
//   - header: lodforge version, config file, input and output folders, jobs, shard and the summary figures;
//   - changes since the previous run (report.json "changes"), when present;
//   - failures: path and error of failed assets (the first 200; the table filters by status for all);
//   - the assets table: one row per asset, failed first, then assets with a LOD that missed its budget, then by
//     the largest measured Hausdorff distance; search, class and status filters; every column sorts; a row
//     expands to its LODs and a plot of Hausdorff and mean error against triangles, the chain from the source
//     connected, on log axes shared by every asset (zero errors on a row of their own), and the asset's LOD
//     pictures when the run drew them (report_files/<asset>/lodK.png beside the page, loaded lazily);
//   - error against triangles by class: every LOD of every asset, one canvas per class on the same axes, drawn
//     when the folded section is opened;
//   - the ten assets with the largest Hausdorff distance, one bar each;
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
