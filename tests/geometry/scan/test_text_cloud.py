"""Text point clouds in the dialects scanners and clinic software write (app.geometry.scan.text_cloud):
each reads to the same points, and a file none of them describes is refused with the row at fault."""

import numpy as np
import pytest
import trimesh

from app.geometry.errors import FailureReason, FitFailure
from app.geometry.scan.reader import load_scan
from app.geometry.scan.text_cloud import decimal_comma, read_text_cloud
from tests.conftest import REAL


@pytest.fixture(scope="module")
def skin_points():
    """(20000, 3) mm: points on BodyParts3D's leg (a real scan's skin), 3 decimals."""
    return np.round(trimesh.load(REAL / "bodyparts3d_right_leg.stl").sample(20000, seed=1), 3)


def _rows(points, template, decimal=".", extra=lambda i: ""):
    """One row per point: ``template`` formats x, y, z (3 decimals), ``decimal`` their mark."""
    return [template.format(*(f"{c:.3f}".replace(".", decimal) for c in p)) + extra(i) for i, p in enumerate(points)]


DIALECTS = {
    "spaces": ("{} {} {}", ".", "", "\n"),
    "comma csv with a header": ("{},{},{}", ".", "x,y,z\n", "\n"),
    "comma and space": ("{}, {}, {}", ".", "", "\n"),
    "tabs, Windows line ends": ("{}\t{}\t{}", ".", "X\tY\tZ\r\n", "\r\n"),
    # a German or French locale's export: decimal commas, semicolons (Excel) or tabs between
    "decimal commas, semicolons": ("{};{};{}", ",", "X [mm];Y [mm];Z [mm]\r\n", "\r\n"),
    "decimal commas, tabs": ("{}\t{}\t{}", ",", "", "\n"),
    "decimal commas, spaces": ("{} {} {}", ",", "", "\n"),
}


@pytest.mark.parametrize("dialect", DIALECTS)
def test_every_dialect_reads_to_the_same_points(skin_points, dialect):
    template, decimal, header, newline = DIALECTS[dialect]
    text = header + newline.join(_rows(skin_points, template, decimal))
    assert np.array_equal(read_text_cloud(text.encode()), skin_points)


def test_extra_columns_pts_counts_and_a_latin1_header_are_read_past(skin_points):
    """Leica PTS: a count row before each scan joined, intensity and colour after x y z
    (some rows without colour); a header naming the clinic in Latin-1."""
    first, second = skin_points[:12000], skin_points[12000:]

    def rows(part):
        return _rows(part, "{} {} {}", extra=lambda i: " -1204 200 180 90" if i % 3 else " -1204")

    text = "\n".join([str(len(first)), *rows(first), str(len(second)), *rows(second)])
    data = "# Sanitätshaus Köln, Scan 3\n".encode("latin-1") + text.encode()
    for fmt in ("txt", "pts", "xyz"):  # Leica's own extension, and the usual ones
        assert np.array_equal(load_scan(data, file_type=fmt).points_mm, skin_points)


def test_decimal_commas_are_told_from_comma_separators():
    def commas_decimal(row):
        return decimal_comma([row], row)

    assert commas_decimal("12,5;130,25;7,5") and commas_decimal("12,5 130,25 7,5")
    assert not commas_decimal("12,130,7")  # a comma CSV of whole millimetres
    assert not commas_decimal("12.5,130.25,7.5") and not commas_decimal("12.5 130.25 7.5")
    assert np.array_equal(read_text_cloud(b"12,130,7\n1,2,3\n"), [[12, 130, 7], [1, 2, 3]])
    assert np.array_equal(read_text_cloud(b"1.5, 2.5, 3.5\n1, 2, 3\n"), [[1.5, 2.5, 3.5], [1, 2, 3]])
    # whole millimetres first, decimal commas further down: decided for the whole file
    assert np.array_equal(read_text_cloud(b"12;130;7\n" * 150 + b"12,5;130,25;7,5\n")[-1], [12.5, 130.25, 7.5])
    # thousands separators of a German spreadsheet's export
    assert np.array_equal(read_text_cloud(b"1.234,5;567,25;1.801\n"), [[1234.5, 567.25, 1801.0]])


@pytest.mark.parametrize("payload,words", [
    (b"1 2 3\n4 5 6\n7.5 8\n1 2 3\n", "row 3 of the point cloud has 2 number(s)"),
    (b"x;y;z\n1,5;2,5;3,5\n1,5;2,5;3,5\n4,5;5,5\n", "row 4 of the point cloud has 2 number(s); each row must start with x y z "
                                         "(its decimals written with commas"),
    (b"1 2 3\n4 5 six\n", "rows are not all numbers"),
    (b"12,5;130,25;7,5\n12.5;130,25;7,5\n", "writes its decimals with commas, but row 2 has a decimal point too"),
    (b"\x00\x00\x80\x3f" * 300, "not text"),
])
def test_a_file_no_dialect_describes_is_refused_with_the_row_at_fault(payload, words):
    with pytest.raises(FitFailure) as info:
        read_text_cloud(payload)
    assert info.value.reason is FailureReason.UNREADABLE_FILE and words in info.value.detail


def test_counts_alone_are_no_points():
    with pytest.raises(FitFailure) as info:
        read_text_cloud(b"# PTS\n20000\n")
    assert info.value.reason is FailureReason.EMPTY_SCAN
