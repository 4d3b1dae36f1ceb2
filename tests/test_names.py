"""Names in the owner's language (issue 22, item 6): the one rule, the waypoints file, the maps folder.

"Küche", "Mum's room" (and the ’ a phone types), "台所", "रसोई" are names, kept in NFC so a name typed on
a Mac and on a phone is one name; what could change meaning in a URL or a path is refused with a
message that quotes the name as typed and says what is allowed. Real files in a temporary folder.
"""

import os
import unicodedata

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from flask_move_server.core import names
from flask_move_server.core.errors import BadMapName, BadWaypoint, MapExists, WaypointFileError, shown
from flask_move_server.maps.catalogue import MapCatalogue, check_map_name
from flask_move_server.maps.mapfile import Grid
from flask_move_server.waypoints import check_name, make_waypoint
from flask_move_server.waypoints.store import WaypointStore
from flask_move_server.waypoints.yaml_format import dump, parse

NFD_KUCHE = unicodedata.normalize("NFD", "Küche")  # as a Mac keyboard (or file name) may give it
GOOD = ["Küche", "Mum's room", "Mum\u2019s room", "台所", "रसोई", "Ку́хня", "Łódź 2", "ΣΑΛΟΝΙ", "كراج", "kitchen",
        "living room", "dock_2", "a-b.c", "x" * 64]


@pytest.mark.parametrize("name", GOOD)
def test_letters_of_any_language_and_apostrophes_are_names(name):
    assert check_name(name) == name
    assert check_map_name(name) == name


def test_a_name_is_kept_composed_whatever_the_keyboard_sent():
    assert NFD_KUCHE != "Küche" and check_name(NFD_KUCHE) == "Küche"
    assert make_waypoint(NFD_KUCHE, 1, 2, 3).name == "Küche"


@pytest.mark.parametrize("name, problem", [
    ("Küche/2", "'/' is not allowed"),
    ("Küche\\2", "'\\' is not allowed"),
    ("Küche%2F", "'%' is not allowed"),
    ("Küche?", "'?' is not allowed"),
    ("Küche#1", "'#' is not allowed"),
    ("Küche\n", "the invisible character U+000A is not allowed"),
    ("Kü\u200bche", "the invisible zero width space U+200B is not allowed"),
    ("Küche\u202e", "the invisible right-to-left override U+202E is not allowed"),
    ("\u0301Küche", "the combining acute accent U+0301 must follow a letter"),
    ("Küche \U0001f373", "'\U0001f373' is not allowed"),
    (" Küche", "it starts or ends with a space"),
    ("...", "'..' and '.' alone are path segments"),
    ("ü" * 65, "it has 65 characters"),
])
def test_a_refused_name_is_quoted_as_typed_with_what_is_wrong_and_what_is_allowed(name, problem):
    with pytest.raises(BadWaypoint) as refused:
        check_name(name)
    message = str(refused.value)
    assert message.startswith("Invalid waypoint name {}: {}; use 1 to 64 letters, digits (of any language), "
                              "spaces, apostrophes (' or \u2019)".format(shown(name), problem)), message
    assert message.endswith('e.g. "Küche" or "Mum\'s room".')
    assert "\\u00fc" not in message and "Küche" in message  # letters as typed, never escaped


def test_a_quoted_name_shows_letters_and_escapes_only_what_prints_nothing():
    assert shown("Küche") == '"Küche"'
    assert shown("a\u202eb\u2028c\x7f") == '"a\\u202eb\\u2028c\\u007f"'


def test_the_file_keeps_names_readable_and_they_come_back_exactly(tmp_path):
    path = tmp_path / "waypoints.yaml"
    store = WaypointStore(str(path))
    for name in ("Küche", "Mum's room", "Mum\u2019s room", "台所", "रसोई", "yes", "2nd floor"):
        store.put(make_waypoint(name, 1.0, 2.0, 0.5))
    text = path.read_text(encoding="utf-8")
    assert "  Küche: [1.0, 2.0, 0.5]\n" in text and "  台所: [1.0, 2.0, 0.5]\n" in text
    assert "  \"Mum's room\": [1.0, 2.0, 0.5]\n" in text and "  \"Mum\u2019s room\": [" in text
    assert "  \"yes\": [" in text and "\\u" not in text  # YAML's booleans quoted; nothing escaped
    assert [wp.name for wp in WaypointStore(str(path)).all()] == [
        "Küche", "Mum's room", "Mum\u2019s room", "台所", "रसोई", "yes", "2nd floor"]


def test_a_hand_written_file_with_quoted_escaped_or_decomposed_keys_loads(tmp_path):
    path = tmp_path / "waypoints.yaml"
    path.write_text('waypoints:\n  "K\\u00fcche": [1, 2, 3]\n  \'Mum\'\'s room\': [4, 5, 6]\n'
                    "  Bu{}ro: [7, 8, 9]\n".format("\u0308"), encoding="utf-8")
    store = WaypointStore(str(path))
    assert [wp.name for wp in store.all()] == ["Küche", "Mum's room", "Büro"]
    assert store.get(NFD_KUCHE).x == 1.0 and store.problem is None
    store.delete("Büro")  # written back in the seed format, names readable
    assert path.read_text(encoding="utf-8") == \
        "waypoints:\n  Küche: [1.0, 2.0, 3.0]\n  \"Mum's room\": [4.0, 5.0, 6.0]\n"


def test_one_name_written_composed_and_decomposed_is_a_name_given_twice(tmp_path):
    path = tmp_path / "waypoints.yaml"
    text = "waypoints:\n  Küche: [1, 2, 3]\n  {}: [4, 5, 6]\n".format(NFD_KUCHE)
    path.write_text(text, encoding="utf-8")
    store = WaypointStore(str(path))
    assert "line 3: a name appears twice" in store.problem
    with pytest.raises(WaypointFileError):
        store.put(make_waypoint("porch", 1, 1, 1))
    assert path.read_text(encoding="utf-8") == text


def test_a_name_in_any_normal_form_finds_and_deletes_the_waypoint(tmp_path):
    store = WaypointStore(str(tmp_path / "waypoints.yaml"))
    assert store.put(make_waypoint(NFD_KUCHE, 1, 2, 3)) is True
    assert store.put(make_waypoint("Küche", 4, 5, 6)) is False  # the same name: replaced, not a second one
    assert store.get(NFD_KUCHE).x == 4.0
    store.delete(NFD_KUCHE)
    assert store.all() == []


names_typed = st.text(st.characters(whitelist_categories=("Lu", "Ll", "Lo", "Nd", "Mn"),
                                    whitelist_characters="_-. '\u2019"), min_size=1, max_size=64)


@settings(max_examples=80, deadline=None)
@given(st.lists(names_typed, min_size=1, max_size=5))
def test_any_valid_unicode_names_survive_a_save_and_load(tmp_path_factory, typed):
    valid = []
    for name in typed:
        try:
            valid.append(check_name(name))
        except BadWaypoint:
            continue
    path = tmp_path_factory.mktemp("unicode") / "w.yaml"
    wps = [make_waypoint(name, i, -i, 0.5) for i, name in enumerate(dict.fromkeys(valid))]
    assert list(parse(dump(wps)).values()) == wps
    store = WaypointStore(str(path))
    for wp in wps:
        store.put(wp)
    assert WaypointStore(str(path)).all() == wps


# maps: names become file names ----------------------------------------------------------------------


def grid():
    return Grid(4, 3, 0.05, 0.0, 0.0, bytes(12))


@pytest.fixture
def catalogue(tmp_path):
    return MapCatalogue(str(tmp_path / "maps"))


def test_a_map_named_in_any_language_is_a_file_of_that_name(catalogue):
    assert catalogue.save(NFD_KUCHE, grid()).name == "Küche"
    assert sorted(os.listdir(catalogue.folder)) == ["Küche.pgm", "Küche.yaml"]  # composed on disk
    assert catalogue.names() == ["Küche"] and catalogue.describe(NFD_KUCHE).name == "Küche"
    assert catalogue.rename("Küche", "Mum's room").name == "Mum's room"
    assert sorted(os.listdir(catalogue.folder)) == ["Mum's room.pgm", "Mum's room.yaml"]


@pytest.mark.parametrize("twin", ["KÜCHE", "küche", unicodedata.normalize("NFD", "KÜCHE")])
def test_map_names_differing_only_in_case_or_composition_are_one_name(catalogue, twin):
    catalogue.save("Küche", grid())
    before = sorted(os.listdir(catalogue.folder))
    with pytest.raises(MapExists, match="'Küche' is saved, and map names must differ in more than case"):
        catalogue.save(twin, grid())
    assert sorted(os.listdir(catalogue.folder)) == before


@pytest.mark.parametrize("name, problem", [
    ("../Küche", "'/' is not allowed"),
    (".Küche", "not starting with '.'"),
    ("Küche.WAYPOINTS", "not ending in '.waypoints'"),
    ("\U00020000" * 51, "too long for a file name: 204 bytes in UTF-8, at most 200"),
])
def test_a_map_name_that_would_be_a_bad_file_name_is_refused_and_nothing_written(catalogue, name, problem):
    with pytest.raises(BadMapName, match=problem.replace(".", "\\.").replace("(", "\\(")):
        catalogue.save(name, grid())
    assert not os.path.exists(catalogue.folder)


def test_the_longest_map_name_fits_every_file_a_save_makes(catalogue):
    name = "\U00020000" * 50  # 200 bytes: 50 letters of CJK extension B, 4 bytes each
    catalogue.save(name, grid())
    WaypointStore(catalogue.waypoints_path(name)).put(make_waypoint("Küche", 1, 2, 3))
    assert catalogue.rename(name, "台所").name == "台所"


def test_names_rule_is_one_text_shared_by_waypoints_and_maps():
    from flask_move_server.maps.catalogue import MAP_NAME_RULE
    from flask_move_server.waypoints import NAME_RULE

    assert NAME_RULE == names.RULE and MAP_NAME_RULE.startswith(names.RULE)


def test_a_map_yaml_names_its_image_readably_even_when_quoted(catalogue):
    catalogue.save("'t Hüs", grid())  # a leading apostrophe: YAML needs the image's name quoted
    text = open(os.path.join(catalogue.folder, "'t Hüs.yaml"), encoding="utf-8").read()
    assert text.startswith("image: \"'t Hüs.pgm\"\n"), text
    assert catalogue.load("'t Hüs").width == 4
