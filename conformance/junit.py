"""JUnit XML from a run's ``Report``: for CI dashboards that read test results.

How it works: one ``<testsuite>`` named after the device and port; its properties carry the firmware,
the port, the seed, the kit version, the unit identity and every information record (what the device
does where docs/protocol.md is silent: information, never a test). Only checks of stated rules are
``<testcase>``s; a failure carries the message and the exchanges as ``system-out``; a check not run is
``<skipped>`` with the reason; a manual step is ``<skipped>`` saying what a person must do. Written with
the standard library's ElementTree (it escapes what XML needs).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

from .report import Report
from .results import ERROR, FAIL, MANUAL, SKIP


def junit_tree(rep: Report) -> ET.ElementTree:
    checks = rep.checks
    failures = sum(r.verdict == FAIL for r in checks)
    errors = sum(r.verdict == ERROR for r in checks)
    skipped = sum(r.verdict in (SKIP, MANUAL) for r in checks) + rep.not_run + rep.deselected
    suite = ET.Element("testsuite", name=f"XA-C1 {rep.version} on {rep.port}", tests=str(rep.total),
                       failures=str(failures), errors=str(errors), skipped=str(skipped),
                       timestamp=rep.date)
    props = ET.SubElement(suite, "properties")
    for name, value in [("firmware", rep.version), ("port", rep.port),
                        ("seed", "derandomized" if rep.seed is None else str(rep.seed)),
                        ("kit version", f"xac1-proto {rep.kit_version}"), ("command line", rep.command_line),
                        ("verdict", rep.verdict_line), ("readings", rep.readings), *rep.unit]:
        ET.SubElement(props, "property", name=name, value=value)
    for info in rep.infos:
        ET.SubElement(props, "property", name=f"information: {info.topic}", value=info.observed)
    for r in checks:
        case = ET.SubElement(suite, "testcase", classname=f"xac1.{r.topic}", name=r.nodeid.split("::")[-1])
        case_props = ET.SubElement(case, "properties")
        ET.SubElement(case_props, "property", name="rule", value=r.rule)
        if r.section:
            ET.SubElement(case_props, "property", name="docs/protocol.md", value=r.section)
        if r.verdict == FAIL:
            ET.SubElement(case, "failure", message=r.message).text = r.message
        elif r.verdict == ERROR:
            ET.SubElement(case, "error", message=r.message).text = r.message
        elif r.verdict == SKIP:
            ET.SubElement(case, "skipped", message=r.message)
        elif r.verdict == MANUAL:
            ET.SubElement(case, "skipped", message=f"manual step: {r.message}")
        if r.probes:
            ET.SubElement(case, "system-out").text = "\n".join(p.show() for p in r.probes)
    for name, why in rep.not_run_checks:
        if name.endswith(" (information)"):
            continue
        case = ET.SubElement(suite, "testcase", classname="xac1", name=name)
        ET.SubElement(case, "skipped", message=why)
    suite.set("tests", str(len(suite.findall("testcase"))))  # manual steps count, as skipped tests
    root = ET.Element("testsuites")
    root.append(suite)
    ET.indent(root)
    return ET.ElementTree(root)


def write_junit(path: Path, rep: Report) -> None:
    """The JUnit XML, written atomically to the file ``path`` names (through a link, to its target)."""
    from xac1_proto.output_file import write_output

    root = junit_tree(rep).getroot()
    assert root is not None  # junit_tree builds it
    write_output(path, ET.tostring(root, encoding="utf-8", xml_declaration=True))
