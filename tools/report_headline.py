# SPDX-License-Identifier: BSD-3-Clause
"""The headline of a run folder's report.html (tools/report.py): what a person reads first, the
verdict, the failures and the key figures beside the reference work's, before the detailed
tables. Pure: a summary.json dictionary in, HTML out (tested by tests/apps/test_report_headline.py)."""
import html

# The reference work's figures for its three experiments (docs/results.md, "Formation error"):
# formation error of the follower [m], by scenario name of config/scenarios/.
REFERENCE = {
    "triangle": {"section": "Sec. 3.3, simulated", "steady_state_formation_error_m": 0.05},
    "manual-leader": {"section": "Sec. 3.4.1, flight", "mean_formation_error_m": 0.14,
                      "steady_state_formation_error_m": 0.11},
    "flying-leader-paper": {"section": "Sec. 3.4.2, flight", "mean_formation_error_m": 0.44},
}

# The key figures: summary key, label, unit, scale to the unit.
KEY_FIGURES = (
    ("steady_state_formation_error_m", "steady-state formation error", "m", 1.0),
    ("mean_formation_error_m", "mean formation error (formation window)", "m", 1.0),
    ("max_formation_error_m", "max formation error (formation window)", "m", 1.0),
    ("solver_time_median_s", "solver time, median", "ms", 1e3),
    ("solver_time_max_s", "solver time, max", "ms", 1e3),
    ("min_separation_m", "min separation of any two vehicles", "m", 1.0),
)


def verdict(summary):
    """(word, sentence): 'incomplete' (interrupted or unstable), 'failed' (entries in
    failures: exit 3, docs/failure.md) or 'passed'."""
    failures = summary.get("failures") or []
    runs = summary.get("runs", 1)
    if not summary.get("complete", False):
        why = summary.get("error") or summary.get("stopped") or "interrupted or unstable"
        return "incomplete", "The run did not complete (%s): its figures cover part of it." % why
    if failures:
        return "failed", "%d failure(s) in %d run(s): the run does not count as a success." % (
            len(failures), runs)
    landed = summary.get("landed_safely")
    tail = "" if landed in (True, None) else (
        " Not every vehicle landed safely: a vehicle downed on purpose by a fault.")
    return "passed", "Every vehicle flew, held the envelope and landed; no failure.%s" % tail


def _figure(value, unit, scale):
    if not isinstance(value, (int, float)) or isinstance(value, bool):
        return "n/a"
    return "%.3g %s" % (value * scale, unit)


def headline_html(summary):
    """The headline section: verdict, failures (kind, vehicle, time, reason) and the key
    figures with the reference work's beside them when the scenario is one of its experiments."""
    word, sentence = verdict(summary)
    colour = {"passed": "#1a7f37", "failed": "#cf222e", "incomplete": "#9a6700"}[word]
    out = ["<section id='headline' style='border:2px solid %s;padding:8px 14px;margin:12px 0'>"
           % colour]
    out.append("<h2 style='color:%s;margin:4px 0'>%s</h2><p>%s</p>" % (
        colour, word.upper(), html.escape(sentence)))
    failures = summary.get("failures") or []
    if failures:
        out.append("<h3>Failures</h3><table><tr><th>run</th><th>vehicle</th><th>kind</th>"
                   "<th>t [s]</th><th>reason</th></tr>")
        for f in failures:
            t = f.get("time_s")
            out.append("<tr><td>%s</td><td>%s</td><td>%s</td><td>%s</td><td>%s</td></tr>" % (
                html.escape(str(f.get("run", ""))),
                html.escape(str(f.get("vehicle", " / ".join(f.get("vehicles", []))))),
                html.escape(str(f.get("kind", ""))),
                "%.2f" % t if isinstance(t, (int, float)) else "",
                html.escape(str(f.get("reason", "")))))
        out.append("</table>")
    reference = REFERENCE.get(summary.get("scenario"))
    runs = summary.get("runs", 1)
    out.append("<h3>Key figures (%d run%s)</h3><table><tr><th></th><th>this run</th>" % (
        runs, "" if runs == 1 else "s, aggregated as in summary.json"))
    if reference:
        out.append("<th>reference work (%s)</th>" % html.escape(reference["section"]))
    out.append("</tr>")
    for key, label, unit, scale in KEY_FIGURES:
        row = "<tr><th align=left>%s</th><td>%s</td>" % (
            html.escape(label), _figure(summary.get(key), unit, scale))
        if reference:
            row += "<td>%s</td>" % (_figure(reference[key], unit, scale) if key in reference
                                    else "")
        out.append(row + "</tr>")
    out.append("</table></section>")
    return "\n".join(out)
