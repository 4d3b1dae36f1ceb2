"""Routes kept in the waypoints file by the WaypointStore (issue 23, item 1).

Real files: what the store writes is read back by a fresh store (as after a restart), the bytes
on disk are compared where nothing may be written, and maps are renamed and marked for real.
"""

import logging

import pytest

from flask_move_server.core.errors import BadRoute, UnknownRoute, WaypointFileError, WaypointInUse
from flask_move_server.maps.catalogue import MapCatalogue
from flask_move_server.maps.marks import MappingMarks
from flask_move_server.missions.route import Route, make_route
from flask_move_server.waypoints import make_waypoint
from flask_move_server.waypoints.store import WaypointStore
from flask_move_server.waypoints.yaml_format import dump, parse, parse_document
from tests.test_maps import small_grid
from tests.test_waypoints import SEED, SEED_WRITTEN

WITH_ROUTES = (  # the contract's example: one line per route
    "waypoints:\n"
    "  kitchen: [8.4, 0.9, 0.0]\n"
    "  office: [-0.8, 4.3, 1.57]\n"
    "  dock: [0.0, 0.0, 0.0]\n"
    "routes:\n"
    "  rounds: {waypoints: [kitchen, office, dock], loops: 1, dwell: 5.0, on_failure: skip, "
    "schedule: [\"mon-fri 09:00\", \"21:30\"]}\n"
    "  night: {waypoints: [office, dock], loops: 0, dwell: 0.0, on_failure: stop, schedule: []}\n"
)


@pytest.fixture
def routes_file(tmp_path):
    path = tmp_path / "waypoints.yaml"
    path.write_text(WITH_ROUTES)
    return path


@pytest.fixture
def seed_file(tmp_path):
    path = tmp_path / "waypoints.yaml"
    path.write_text(SEED)
    return path


def route(name, *stops, **fields):
    return make_route(name, dict(fields, waypoints=list(stops)))


# the format ------------------------------------------------------------------------------------


def test_the_contract_s_example_is_written_back_as_it_was():
    document = parse_document(WITH_ROUTES)
    assert list(document.routes) == ["rounds", "night"]
    assert document.routes["rounds"] == Route("rounds", ("kitchen", "office", "dock"), 1, 5.0, "skip",
                                              ("mon-fri 09:00", "21:30"))
    assert dump(document.waypoints.values(), document.routes.values()) == WITH_ROUTES


NAMES = ["Küche", "Mum's room", "'s Hoekje", "yes", "1.5", "-1", "null", "dock-2", "Bad Zimmer"]


@pytest.mark.parametrize("name", NAMES)
def test_routes_named_anything_a_person_may_write_survive_a_dump_and_parse(name):
    waypoints = [make_waypoint(n, i, i, 0) for i, n in enumerate(NAMES)]
    routes = [route(name, name, "Küche", name, dwell=2, loops=3, schedule=["Sat,Sun 10:15"]),
              route("plain", "dock-2", on_failure="skip")]
    document = parse_document(dump(waypoints, routes))
    assert list(document.routes.values()) == routes
    assert document.routes[name].dwell == 2.0 and document.routes[name].schedule == ("sat,sun 10:15",)
    assert list(document.waypoints.values()) == waypoints


def test_parse_still_gives_the_waypoints_of_a_file_with_routes():
    assert list(parse(WITH_ROUTES)) == ["kitchen", "office", "dock"]


BAD_ENTRIES = [
    pytest.param("  bad: {waypoints: [kitchen], on_failure: whisper}\n", "on_failure", id="bad-policy"),
    pytest.param("  bad: {waypoints: [kitchen], schedule: [\"whisper 9\"]}\n", "schedule", id="bad-time"),
    pytest.param("  bad: {waypoints: [kitchen], whisper: 1}\n", "Unknown field", id="unknown-field"),
    pytest.param("  bad: {waypoints: []}\n", "waypoints", id="no-stops"),
    pytest.param("  bad: {waypoints: [whisper/x]}\n", "waypoint name", id="bad-stop-name"),
    pytest.param("  whisper/x: {waypoints: [kitchen]}\n", "route name", id="bad-route-name"),
    pytest.param("  bad: [kitchen, dock]\n", "object", id="not-a-mapping"),
]


@pytest.mark.parametrize("entry, says", BAD_ENTRIES)
def test_a_bad_route_entry_names_its_line_and_what_is_wrong_never_its_text(entry, says):
    text = WITH_ROUTES + entry  # the eighth line
    with pytest.raises(WaypointFileError) as err:
        parse_document(text, source="w.yaml")
    message = str(err.value)
    assert message.startswith("w.yaml, line 8: ") and says in message
    assert "whisper" not in message


def test_routes_that_are_not_a_mapping_or_lack_waypoints_are_refused_with_the_line():
    with pytest.raises(WaypointFileError, match="line 5: 'routes' must map names"):
        parse_document(SEED + "routes: [kitchen, dock]\n")
    with pytest.raises(WaypointFileError, match="line 1: 'routes' needs 'waypoints:'"):
        parse_document("routes:\n  r: {waypoints: [kitchen]}\n")


def test_a_route_name_given_twice_composed_differently_is_refused():
    text = SEED + "routes:\n  K\u00fcche: {waypoints: [dock]}\n  Ku\u0308che: {waypoints: [dock]}\n"
    with pytest.raises(WaypointFileError, match="line 7: a route name appears twice"):
        parse_document(text)


# the store -------------------------------------------------------------------------------------


def test_a_seed_file_gets_no_routes_written_by_a_waypoint_change(seed_file):
    WaypointStore(seed_file).put(make_waypoint("dock", 0.0, 0.0, 0.0))
    assert seed_file.read_text() == SEED_WRITTEN


def test_deleting_the_last_route_writes_the_seed_format_again(seed_file):
    store = WaypointStore(seed_file)
    store.put_route(route("rounds", "kitchen", "dock"))
    assert "routes:" in seed_file.read_text()
    store.delete_route("rounds")
    assert seed_file.read_text() == SEED_WRITTEN


def test_routes_load_in_file_order_and_each_by_name(routes_file):
    store = WaypointStore(routes_file)
    assert [r.name for r in store.routes()] == ["rounds", "night"]
    assert store.get_route("night").loops == 0


def test_a_route_put_is_saved_before_the_answer_and_read_back_after_a_restart(seed_file):
    store = WaypointStore(seed_file)
    announced = []
    store.when_changed(announced.append)
    assert store.put_route(route("rounds", "kitchen", "office", dwell=5)) is True
    assert store.put_route(route("rounds", "office", "dock")) is False
    assert announced == [1, 2]
    assert WaypointStore(seed_file).routes() == [Route("rounds", ("office", "dock"))]


def test_a_route_through_unknown_waypoints_names_each_and_writes_nothing(routes_file):
    store = WaypointStore(routes_file)
    before = routes_file.read_bytes()
    with pytest.raises(BadRoute) as err:
        store.put_route(route("tour", "kitchen", "attic", "cellar", "attic"))
    assert '"attic"' in str(err.value) and '"cellar"' in str(err.value) and '"kitchen"' not in str(err.value)
    assert routes_file.read_bytes() == before and store.version == 0
    with pytest.raises(UnknownRoute):
        store.get_route("tour")


def test_deleting_a_waypoint_a_route_goes_through_names_the_routes_and_writes_nothing(routes_file):
    store = WaypointStore(routes_file)
    before = routes_file.read_bytes()
    with pytest.raises(WaypointInUse) as err:
        store.delete("dock")
    assert str(err.value) == ('The waypoint "dock" is used by the routes "rounds", "night": change or delete them '
                              'first.')
    assert routes_file.read_bytes() == before
    store.delete_route("night")
    with pytest.raises(WaypointInUse, match='by the route "rounds": change or delete it first'):
        store.delete("dock")
    store.put_route(route("rounds", "kitchen"))
    store.delete("dock")
    assert [w.name for w in WaypointStore(routes_file).all()] == ["kitchen", "office"]


@pytest.mark.parametrize("overwrite", [False, True])
def test_a_renamed_waypoint_is_renamed_in_every_route_in_the_same_save(routes_file, overwrite):
    store = WaypointStore(routes_file)
    new = "kitchen" if overwrite else "Büro"
    store.rename("office", new, overwrite=overwrite)
    routes = {r.name: r.waypoints for r in WaypointStore(routes_file).routes()}
    assert routes == {"rounds": ("kitchen", new, "dock") if not overwrite else ("kitchen", "kitchen", "dock"),
                      "night": (new, "dock")}


def test_an_unknown_route_suggests_close_names_or_where_to_look(routes_file):
    store = WaypointStore(routes_file)
    with pytest.raises(UnknownRoute) as err:
        store.get_route("Rounds")
    assert str(err.value) == 'No route named "Rounds". Did you mean: "rounds"?'
    with pytest.raises(UnknownRoute) as err:
        store.delete_route("patrol")
    assert str(err.value) == 'No route named "patrol". GET /routes lists them.'


def test_routes_edited_on_disk_are_picked_up_and_kept_by_the_next_save(seed_file):
    store = WaypointStore(seed_file)
    announced = []
    store.when_changed(announced.append)
    seed_file.write_text(SEED + "routes:\n  tour: {waypoints: [dock, kitchen]}\n")
    assert store.routes() == [Route("tour", ("dock", "kitchen"))] and announced == [1]
    store.put(make_waypoint("porch", 1, 1, 1))
    assert [r.name for r in WaypointStore(seed_file).routes()] == ["tour"]


def test_a_broken_route_edited_in_keeps_the_last_good_routes_and_refuses_changes(routes_file):
    store = WaypointStore(routes_file)
    broken = WITH_ROUTES + "  bad: {waypoints: [dock], loops: -1}\n"
    routes_file.write_text(broken)
    assert [r.name for r in store.routes()] == ["rounds", "night"]
    assert "line 8" in store.problem
    with pytest.raises(WaypointFileError, match="nothing was changed"):
        store.put_route(route("tour", "dock"))
    assert routes_file.read_text() == broken


def test_a_hand_edited_route_through_a_missing_waypoint_loads_with_one_warning(seed_file, caplog):
    seed_file.write_text(SEED + "routes:\n  tour: {waypoints: [dock, attic]}\n")
    with caplog.at_level(logging.WARNING, logger="flask_move_server.waypoints.store"):
        store = WaypointStore(seed_file)
        for _ in range(3):
            assert store.get_route("tour").waypoints == ("dock", "attic")
    warnings = [r.getMessage() for r in caplog.records if "attic" in r.getMessage()]
    assert len(warnings) == 1 and '"tour"' in warnings[0] and "miss" in warnings[0]


def test_a_route_without_a_name_is_not_kept(seed_file):
    with pytest.raises(BadRoute, match="needs a name"):
        WaypointStore(seed_file).put_route(make_route(None, {"waypoints": ["dock"]}, scheduled=False))
    assert seed_file.read_text() == SEED


# maps --------------------------------------------------------------------------------------------


def test_renaming_a_map_keeps_its_routes(tmp_path):
    maps = MapCatalogue(str(tmp_path / "maps"))
    maps.save("flat", small_grid())
    store = WaypointStore(maps.waypoints_path("flat"))
    store.put(make_waypoint("dock", 0, 0, 0))
    store.put_route(route("rounds", "dock", loops=2))
    assert maps.rename("flat", "home").waypoints == 1
    assert WaypointStore(maps.waypoints_path("home")).routes() == [Route("rounds", ("dock",), loops=2)]


def test_routes_made_while_mapping_go_to_the_saved_map(tmp_path):
    marks = MappingMarks(str(tmp_path / "state" / "mapping.waypoints.yaml"))
    marks.start_afresh()
    store = WaypointStore(marks.path)
    store.put(make_waypoint("sofa", 1, 2, 0))
    store.put_route(route("tour", "sofa", dwell=3))
    target = tmp_path / "maps" / "home.waypoints.yaml"
    target.parent.mkdir()
    assert marks.give_to(str(target)) == 1
    assert WaypointStore(target).routes() == [Route("tour", ("sofa",), dwell=3.0)]
