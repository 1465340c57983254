"""Attribute parsing and breakdown, the HTML report (rendered in headless Chromium), ``--compare``."""

from __future__ import annotations

import json
import re
import shutil
import subprocess

import numpy as np
import pytest

from conftest import SEQUENCES
from vidtrack.cli import main as vidtrack_main
from vidtrack.errors import DatasetError
from vidtrack.eval.attributes import by_attribute, find_attribute_file, parse_attributes, read_attributes, tag_order
from vidtrack.eval.compare import compare, format_comparison
from vidtrack.eval.html_report import strip_rows
from vidtrack.eval.synthetic import write_sequence

ATTR_TEXT = "Girl\tSV, OCC, IPR, OPR\nDavid\tIV, SV, OCC, DEF, MB, IPR, OPR\n\n# a comment\nMan  IV\n"


def test_parse_otb_attribute_file():
    table = parse_attributes(ATTR_TEXT)
    assert table == {"Girl": ("SV", "OCC", "IPR", "OPR"), "David": ("IV", "SV", "OCC", "DEF", "MB", "IPR", "OPR"),
                     "Man": ("IV",)}  # tab (OTB) or, failing that, spaces after the name
    assert parse_attributes("Suv\tocc,ipr , OV")["Suv"] == ("OCC", "IPR", "OV")
    for bad, message in (("Girl\n", "expected 'name<TAB>TAG"), ("Girl\tSV, O C C", "not an attribute tag"),
                         ("Girl\tSV\nGirl\tOCC", "listed twice")):
        with pytest.raises(DatasetError, match=message):
            parse_attributes(bad, source="attr_list.txt")
    assert tag_order({"LR", "ARC", "IV", "OCC"}) == ["IV", "OCC", "LR", "ARC"]  # OTB's order, then others


@pytest.mark.skipif(not (SEQUENCES / "attr_list.txt").is_file(), reason="shared sequences not present")
def test_shared_attribute_file_tags_every_shared_sequence():
    table = read_attributes(find_attribute_file(SEQUENCES))
    folders = {p.name for p in SEQUENCES.iterdir() if (p / "img").is_dir() or (p / "imgs").is_dir()}
    assert set(table) == folders and table["Suv"] == ("OCC", "IPR", "OV") and table["FaceOcc1"] == ("OCC",)
    assert find_attribute_file(SEQUENCES / "Girl") == SEQUENCES / "attr_list.txt"  # one sequence: the parent's


def test_by_attribute_means_over_the_tagged_sequences():
    summary = {"a": {"Girl": {"auc": 0.6}, "David": {"auc": 0.2}, "Man": {"auc": None, "error": "x"},
                     "Other": {"auc": 0.9}, "mean": {"auc": 0.5}}}
    table = by_attribute(summary, parse_attributes(ATTR_TEXT))["a"]
    assert list(table) == ["IV", "SV", "OCC", "DEF", "MB", "IPR", "OPR"]
    assert table["SV"] == {"auc": pytest.approx(0.4), "sequences": 2}
    assert table["IV"] == {"auc": 0.2, "sequences": 1}  # Man failed: left out; Other has no tags


def test_strip_rows_pick_the_first_failures():
    ious = np.full(40, np.nan)
    ious[::2] = 0.9
    ious[[10, 12, 14]] = 0.1  # failure starting at row 10
    ious[30] = 0.2  # another one at row 30
    ious[20] = 0.45  # below PASCAL's 0.5 but not visibly off: not a failure here
    assert strip_rows(ious, count=4) == [0, 10, 30, 38]
    assert strip_rows(ious, count=6) == [0, 6, 10, 16, 30, 38]  # filled with evenly spaced scored rows
    assert strip_rows(np.full(5, np.nan)) == []


def _dataset(tmp_path):
    data = tmp_path / "data"
    write_sequence(data / "Otb", layout="otb", frames=16, size=(96, 72))
    write_sequence(data / "Mil", layout="mil", frames=21, size=(128, 72), first_number=0, annotate_every=5,
                   box=(20, 30, 18, 16), velocity=(2.5, -0.5))
    (data / "attr_list.txt").write_text("Otb\tSV, OCC\nMil\tOCC, FM\n")
    return data


def _chromium() -> str | None:
    return shutil.which("chromium") or shutil.which("chromium-browser")


def test_eval_writes_attributes_confidence_and_a_report_that_renders(tmp_path, capsys):
    data = _dataset(tmp_path)
    out = tmp_path / "r"
    assert vidtrack_main(["eval", str(data), "--filter", "kalman-cv,ms", "--out", str(out), "-q", "--in-process"]) == 0
    printed = capsys.readouterr().out
    assert "| filter" in printed and "conf. ROC AUC" in printed and "OCC (2)" in printed
    summary = json.loads((out / "summary.json").read_text())
    by_attr = summary["by_attribute"]
    assert set(by_attr) == {"kalman-cv", "ms"} and list(by_attr["ms"]) == ["SV", "OCC", "FM"]
    assert by_attr["ms"]["OCC"]["sequences"] == 2
    assert by_attr["ms"]["OCC"]["auc"] == pytest.approx((summary["ms"]["Otb"]["auc"] + summary["ms"]["Mil"]["auc"]) / 2)
    assert by_attr["ms"]["FM"]["auc"] == pytest.approx(summary["ms"]["Mil"]["auc"])
    for name in ("kalman-cv", "ms"):
        assert {"false_lost", "missed_loss", "confidence_auc"} <= set(summary[name]["mean"])
    assert (out / "attributes.png").read_bytes()[:4] == b"\x89PNG"

    page = (out / "report.html").read_text()
    sources = re.findall(r'<img[^>]* src="([^"]*)"', page)
    # 3 plots + per sequence up to 6 thumbnails, all inline: the file opens from disk alone
    assert len(sources) >= 3 + 2 * 3 and all(s.startswith("data:image/") for s in sources)
    assert "http" not in page.replace("http-equiv", "") and "<table class=\"sortable\">" in page
    assert "Success AUC by attribute" in page and "Can the confidence be trusted?" in page

    browser = _chromium()
    if browser is None:
        pytest.skip("chromium is not installed (make test installs it when run as root)")
    shot = tmp_path / "report.png"
    flags = ["--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars", f"--user-data-dir={tmp_path / 'profile'}"]
    subprocess.run([browser, *flags, "--window-size=1280,2000", f"--screenshot={shot}", (out / "report.html").as_uri()],
                   check=True, capture_output=True, timeout=120)
    png = shot.read_bytes()
    assert png[:4] == b"\x89PNG" and len(png) > 20_000
    import cv2

    image = cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR)
    assert image.shape[:2] == (2000, 1280) and image.std() > 20  # not a blank page
    dom = subprocess.run([browser, *flags, "--dump-dom", (out / "report.html").as_uri()], check=True,
                         capture_output=True, text=True, timeout=120).stdout
    loaded = re.search(r'data-images="(\d+)/(\d+)"', dom)
    assert loaded is not None, "the page's load script did not run"
    assert loaded.group(1) == loaded.group(2) == str(len(sources))  # every plot and thumbnail decoded

    # the inline sorting script: a click on "AUC" of the per-sequence table orders its rows by AUC, highest first
    click = ("<script>window.addEventListener('load', function () { var t = document.querySelectorAll("
             "'table.sortable')[3]; t.tHead.rows[0].cells[2].click(); document.body.setAttribute('data-order', "
             "Array.prototype.map.call(t.tBodies[0].rows, function (r) { return r.cells[0].textContent + '/' + "
             "r.cells[1].textContent; }).join(',')); });</script></body>")
    clicked = tmp_path / "clicked.html"
    clicked.write_text(page.replace("</body>", click))
    dom = subprocess.run([browser, *flags, "--dump-dom", clicked.as_uri()], check=True, capture_output=True,
                         text=True, timeout=120).stdout
    order = re.search(r'data-order="([^"]*)"', dom).group(1).split(",")
    aucs = [summary[key.split("/")[0]][key.split("/")[1]]["auc"] for key in order]
    assert len(order) == 4 and aucs == sorted(aucs, reverse=True)


def test_attribute_option_and_its_errors(tmp_path, capsys):
    data = _dataset(tmp_path)
    other = tmp_path / "attrs.txt"
    other.write_text("Otb\tLR\n")
    out = tmp_path / "r"
    base = ["eval", str(data), "--filter", "ms", "--out", str(out), "-q", "--in-process", "--no-plots"]
    assert vidtrack_main(base + ["--attributes", str(other)]) == 0
    assert json.loads((out / "summary.json").read_text())["by_attribute"] == {
        "ms": {"LR": {"auc": pytest.approx(json.loads((out / "summary.json").read_text())["ms"]["Otb"]["auc"]),
                      "sequences": 1}}}
    capsys.readouterr()
    assert vidtrack_main(base + ["--attributes", str(tmp_path / "missing.txt")]) == 2
    assert capsys.readouterr().err.strip().count("\n") == 0
    other.write_text("Otb\n")
    assert vidtrack_main(base + ["--attributes", str(other)]) == 2
    err = capsys.readouterr().err
    assert "expected 'name<TAB>TAG" in err and "Traceback" not in err


def test_compare_two_result_folders(tmp_path, capsys):
    a, b = tmp_path / "a", tmp_path / "b"
    for folder, rows in ((a, {"mil": {"Girl": 0.70, "David": 0.50}, "kcf": {"Girl": 0.4}}),
                         (b, {"mil": {"Girl": 0.60, "David": 0.52, "Suv": 0.3}, "csrt": {"Girl": 0.8}})):
        folder.mkdir()
        summary = {name: {**{s: {"auc": v} for s, v in seqs.items()}, "mean": {"auc": 0}} for name, seqs in rows.items()}
        summary["by_attribute"] = {"mil": {"OCC": {"auc": 0.1, "sequences": 1}}}
        (folder / "summary.json").write_text(json.dumps(summary))
    from vidtrack.eval.compare import read_summary

    rows = compare(read_summary(a), read_summary(b))
    by_key = {(r["filter"], r["sequence"]): r for r in rows}
    assert by_key[("mil", "Girl")]["delta"] == pytest.approx(-0.10)
    assert by_key[("mil", "mean")]["delta"] == pytest.approx((-0.10 + 0.02) / 2)  # Suv is only in B
    assert by_key[("mil", "Suv")]["delta"] is None and by_key[("kcf", "mean")]["sequences"] == 0
    table = format_comparison(rows)
    assert re.search(r"\| mil +\| Girl .*-0\.100 \| worse", table) and "| Suv" not in table
    assert "(1 tracker/sequence pair only in A; 2 tracker/sequence pairs only in B: not compared)" in table
    assert "| kcf" not in table and "| csrt" not in table  # nothing in common: no row
    assert "by_attribute" not in table

    assert vidtrack_main(["eval", "--compare", str(a), str(b)]) == 0
    assert "| mil    | Girl" in capsys.readouterr().out
    assert vidtrack_main(["eval", "--compare", str(a), str(tmp_path / "nowhere")]) == 2
    err = capsys.readouterr().err
    assert "has no summary.json" in err and err.count("\n") == 1
    assert vidtrack_main(["eval", str(a), "--compare", str(a), str(b)]) == 2
    assert vidtrack_main(["eval", str(a)]) == 2
    assert "DATASET_DIR and --filter are required" in capsys.readouterr().err
