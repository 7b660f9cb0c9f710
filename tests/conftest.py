"""Shared fixtures: plants on free localhost ports, twins and a running worker."""

from __future__ import annotations

import asyncio
import contextlib
import os
import subprocess
import sys
import time
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path

import pytest

# the source folder's build tools (tools/) and the app in a process of its own as the benchmarks start it
# (standard library only: bench/liveapp.py)
sys.path.append(str(Path(__file__).resolve().parent.parent))
sys.path.append(str(Path(__file__).resolve().parent.parent / "bench"))
# the tests live in folders by layer; the shared helpers (webutil, plants, ...) here, and a test may import
# another's fixture or plant (from test_electrak import lift) across the folders
TESTS = Path(__file__).resolve().parent
sys.path[:0] = [str(TESTS)] + [str(TESTS / layer) for layer in ("app", "browser", "devices", "pages", "safety")]

from liveapp import CHROMIUM_ARGS, free_port, free_udp_port, wait_devices_online  # noqa: E402
from plants import heater_and_lock, modbus_plant  # noqa: E402
import page_events  # noqa: E402

from app.plant import Plant, parse_plant  # noqa: E402


def pytest_configure(config: pytest.Config) -> None:
    """Every runtime the tests start (in this process and in app subprocesses, which inherit the
    environment) keeps its audit log, backups and sessions in a data folder of this test run,
    never in the user's own folder and never shared with a run beside it. Tests that need a
    folder of their own still set ``COMMISSION_DATA_DIR`` themselves."""
    import os
    import tempfile

    global _RUN_DATA_DIR
    # a test that holds a motion would run its process's threads real-time (app/realtime.py): two test
    # processes beside chromium and mosquitto on two cores would starve those; tests of it turn it on themselves
    os.environ.setdefault("COMMISSION_RT_HOLDERS", "0")
    from app import realtime

    realtime.HOLDERS_REAL_TIME = os.environ["COMMISSION_RT_HOLDERS"] != "0"
    if "COMMISSION_DATA_DIR" not in os.environ:
        os.environ["COMMISSION_DATA_DIR"] = os.environ[RUN_DIR_VARIABLE] = tempfile.mkdtemp(prefix="commission-tests-")
    # pytest-xdist's workers inherit the folder the controller made: theirs too (each test module and test then gets
    # a folder of its own below, as in one process). Taken as a folder chosen by whoever started the tests, every
    # app of every worker shared one record and audit log: a test altering the record in one worker showed another
    # worker's record page an altered record.
    if os.environ.get(RUN_DIR_VARIABLE) == os.environ["COMMISSION_DATA_DIR"]:
        _RUN_DATA_DIR = os.environ["COMMISSION_DATA_DIR"]
    config.pluginmanager.register(_Dealer(), "commission-dealer")  # the order of the tests where processes steal work


_RUN_DATA_DIR: str | None = None
RUN_DIR_VARIABLE = "COMMISSION_TEST_RUN_DIR"  # the data folder this test run made (not one given by whoever started it)


# -- markers: the fast loop is ``pytest -m "not browser and not slow"`` ------------------------

#: test files that drive a real browser but are not named test_browser_*.py
BROWSER_FILES = {
    "test_backup_page_browser.py",
    "test_deadman_browser.py",
    "test_mqtt_browser.py",
    "test_stylesheet_browser.py",
}

#: test files that hold a device, a bus or a page to a real-time bound (a keep-alive period, the dead-man
#: bound, a poll cycle against the wire time): ``-m realtime`` runs just them; the whole suite
#: (tools/suite.py) never runs them beside a browser test, whose chromium and app take the cores.
REALTIME_FILES = {
    "test_beat_on_demand.py",
    "test_can_flood.py",
    "test_deadman_browser.py",
    "test_deadman_worker.py",
    "test_electrak.py",
    "test_electrak_control.py",
    "test_faces_opcua_login.py",  # the loop's longest stand-still while passwords are checked off it
    "test_idle_periods.py",
    "test_keepalive_gc.py",
    "test_keepalive_lease.py",
    "test_m3io.py",
    "test_m3io_outputs.py",
    "test_modbus_line_cycle.py",
    "test_modbus_stale.py",
    "test_mo64_rs485.py",
    "test_realtime.py",
    "test_runtime.py",
    "test_scale_plant.py",
    "test_scu_adapter.py",
    "test_scu_faults.py",
    "test_scu_keepalive.py",
    "test_scu_page.py",
    "test_scu_safety.py",
    "test_scu_sim.py",  # the twin runs on a loop of its own: the test's telegrams come on time or not, as a master's
    "test_serial_line.py",
    "test_state_push.py",
    "test_transmit.py",
}

#: tests that take more than about a second on two cores shared with other programs (measured with
#: ``--durations=0`` of the fast loop): a file name (every test in it, where most of its tests are slow)
#: or a node id without its parameters (every parametrisation). The fast loop leaves them out.
SLOW_TESTS: set[str] = {
    # measured 2026-11-29 04:15 UTC at 1.5 s or more in the fast loop (the German pages, each a whole page built and
    # read in German, and the new German tests of the bus tools and the Modbus line)
    "test_i18n_pages.py",
    "test_mqtt_site.py::test_sigkill_of_an_instance_marks_its_devices_vanished",
    "test_i18n_bus_verdicts.py::test_the_transmit_lists_refusal_and_confirmation_in_german",
    "test_i18n_bus_tools.py::test_the_pages_of_an_unknown_bus_device_and_tool_in_german",
    "test_i18n_bus_tools.py::test_a_replays_screening_question_and_summary_in_german",
    "test_i18n_bus_tools.py::test_the_line_monitors_own_words_of_a_transaction_in_german",
    "test_electrak_page_cost.py::test_a_telegram_with_the_same_values_draws_nothing_and_the_round_draws_ages",
    "test_i18n_modbus_line.py::test_a_silent_locks_timeout_in_german_on_its_page_the_overview_and_the_monitor",
    "test_i18n_modbus_line.py::test_the_modbus_polls_exception_and_timeout_in_german",
    "test_i18n_device_params.py::test_the_electrak_timeout_asks_and_refuses_in_german",
    # measured 2026-11-29 at 1.5 s or more in the fast loop (its new German page tests among them)
    "test_i18n.py::test_commission_backup_says_why_a_device_has_nothing_to_back_up_in_german",
    "test_i18n_other_master.py::test_the_m3io_page_refuses_control_while_another_master_is_heard_in_german",
    "test_i18n_bus_tools.py::test_the_overviews_bus_line_words_the_can_controllers_state_in_german",
    "test_mqtt_site.py::test_device_going_offline_shows_offline_in_the_view",
    "test_m3io_params.py::test_on_the_demo_plant_heater_hmrs_project_differs_applies_and_a_change_shows_as_drift",
    "test_m3io_params.py::test_a_project_shows_its_differences_and_applies_them_per_row_and_p2_survives_a_restart",
    "test_m3io_params.py::test_strict_twin_without_p2_and_with_a_slow_store",
    "test_m3io_params.py::test_drift_of_a_changed_record_on_the_overview_and_in_the_api",
    "test_m3io.py::test_blown_fuse_cleared_after_the_module_was_reset",
    "test_i18n_bus_tools.py::test_a_recorded_files_errors_in_german",
    "test_i18n_project.py::test_the_project_card_applies_and_refuses_in_german",
    "test_sleeps.py::test_every_constant_sleep_names_its_reason",
    "test_i18n_bus_tools.py::test_the_transmit_lists_refusal_in_german",
    "test_i18n_device_answers.py::test_the_hdlock_can_status_card_words_the_source_in_german",
    "test_i18n_device_params.py::test_the_p2_switch_asks_its_risk_in_german",
    "test_i18n_device_answers.py::test_the_hdlock_page_words_an_address_change_in_german",
    # a checkout on the demo plant's lock, then the record read again, in German (2026-11-29, 10 s)
    "test_i18n_checkout.py::test_a_checkout_run_is_worded_in_german_after_a_restart",
    "test_can_reader_idle.py::test_a_quiet_udp_multicast_bus_is_read_with_the_longest_wait",
    "test_scale_plant.py",
    "test_metrics.py",
    "test_mo64_params_paths.py",
    "test_m3io_params.py::test_the_replacement_assistant_restores_the_approved_records_on_a_new_module",
    "test_m3io_params_page.py",
    "test_scu_model.py::test_drift_after_a_reset_and_the_replacement_assistant_writes_the_approved_set_back",
    "test_scu_model.py::test_on_the_demo_plant_lift_1s_project_differs_applies_and_a_reset_shows_as_drift",
    "test_scu_model_pages.py",
    "test_api.py",
    "test_audit_page.py",
    "test_backup.py",
    "test_backup_page.py",
    "test_checkout_electrak.py",
    "test_checkout_hdlock.py",
    "test_checkout_m3io.py",
    "test_checkout_mo64.py",
    "test_checkout_scu.py",
    "test_electrak_control.py",
    "test_electrak_page_entries.py",
    "test_faces_mqtt_broker.py",
    "test_faces_opcua_limits.py",
    "test_faces_opcua_login.py",
    "test_hdlock_page.py",
    "test_hdlock_page_cost.py",
    "test_hdlock_page_display.py",
    "test_hdlock_param_grid_and_send_gate.py",
    "test_hdlock_settings_period.py",
    "test_headless_checkout.py",
    "test_keepalive_lease.py",
    "test_live_parity.py",
    "test_m3io_page_cost.py",
    "test_mo64_page_roles.py",
    "test_mo64_rs485.py",
    "test_modbus_line_cycle.py",
    "test_modbus_poll_windows.py",
    "test_monitor_dbc.py",
    "test_monitor_lines_pages.py",
    "test_opcua.py",
    "test_pages_m3io_control_gate.py",
    "test_pages_motion_entries.py",
    "test_pages_roles.py",
    "test_param_entry.py",
    "test_project_page.py",
    "test_record.py",
    "test_record_cli.py",
    "test_record_page_signoff.py",
    "test_replay_page.py",
    "test_runtime.py",
    "test_scu_api.py",
    "test_scu_keepalive.py",
    "test_scu_page.py",
    "test_scu_safety.py",
    "test_scu_sim.py",  # the twin runs on a loop of its own: the test's telegrams come on time or not, as a master's
    "test_security.py",
    "test_security_probes.py",
    "test_sparkplug.py",
    "test_transmit_pages.py",
    "test_widgets_live.py",
    "test_auth.py::test_engineer_can_write",
    "test_auth.py::test_pages_need_login",
    "test_auth.py::test_public_plant_view",
    "test_auth.py::test_viewer_reads_but_cannot_write",
    "test_auth.py::test_wrong_password",
    "test_batch.py::test_cli_apply_confirmations_and_stop",
    "test_can_flood.py::test_flood_is_shed_and_counted_and_the_other_bus_keeps_its_keepalive",
    "test_cli.py::test_backup_skips_a_device_with_nothing_to_back_up",
    "test_cli.py::test_ctrl_c_stops_the_gui_with_one_line",
    "test_cli.py::test_gui_worker_talks_to_commission_sim_in_another_process",
    "test_cli.py::test_restore_yes_refuses_risky_values_unless_named",
    "test_codec_fuzz.py::test_decode_raises_only_its_named_error",
    "test_electrak.py::test_chart_target_only_while_the_actuators_are_driven_to_it",
    "test_electrak.py::test_move_to_target_and_arrive",
    "test_electrak.py::test_only_one_session_controls",
    "test_electrak.py::test_overload_cleared_by_moving_back",
    "test_electrak.py::test_overload_trips_and_clears",
    "test_electrak.py::test_parameter_flag_for_bad_values",
    "test_electrak.py::test_release_sends_enable_cleared_and_stops_keepalive",
    "test_electrak.py::test_timeout_flag_when_control_stops",
    "test_electrak.py::test_too_few_devices_and_override",
    "test_electrak_defects.py::test_go_is_refused_after_an_override_while_an_actuator_is_missing",
    "test_electrak_defects.py::test_go_through_the_gate_asks_that_the_area_is_clear",
    "test_electrak_defects.py::test_override_through_the_gate_asks_first",
    "test_electrak_defects.py::test_override_without_confirmation_is_refused_by_the_adapter",
    "test_electrak_page_cost.py::test_the_page_is_built_from_a_bounded_number_of_elements",
    "test_electrak_service.py::test_bitrate_is_read_back_and_saved_then_applies_at_power_up",
    "test_electrak_service.py::test_read_fails_when_an_actuator_is_missing",
    "test_electrak_service.py::test_unsaved_bitrate_is_lost_at_power_up",
    "test_faces_sparkplug.py::test_fuzz_of_malformed_commands_is_bounded",
    "test_files_inputs.py::test_apply_from_says_what_the_source_is",
    "test_files_inputs.py::test_restore_refuses_dev_zero_and_a_fifo",
    "test_files_project_save.py::test_two_saves_at_the_same_moment_keep_both",
    "test_full_collections.py::test_freeze_startup_heap_counts_what_it_froze",
    "test_hdlock_adapter.py::test_broadcast_set_address_collision_is_reported",
    "test_hdlock_adapter.py::test_broadcast_set_address_nobody_meets_the_condition",
    "test_hdlock_adapter.py::test_broadcast_set_address_other_lock_moves",
    "test_hdlock_adapter.py::test_broadcast_set_address_taken_by_the_lock_that_meets_the_condition",
    "test_hdlock_adapter.py::test_door_closes_and_bolt_locks",
    "test_hdlock_adapter.py::test_set_address_accepted",
    "test_hdlock_adapter.py::test_set_address_lost_lock_is_reported",
    "test_hdlock_adapter.py::test_set_address_refused",
    "test_hdlock_adapter.py::test_timeout_when_twin_silent_and_recovery",
    "test_hdlock_can.py::test_across_processes_on_udp_multicast",
    "test_hdlock_can.py::test_door_closing_seen_in_status_frames",
    "test_hdlock_can.py::test_fwu_status_is_shown",
    "test_hdlock_can.py::test_interface_that_cannot_open_is_reported",
    "test_hdlock_can.py::test_set_bitrate_leaves_the_bus",
    "test_hdlock_can.py::test_set_device_address_then_answers_under_new_id",
    "test_hdlock_can.py::test_set_lock_request_source_command",
    "test_hdlock_can.py::test_unknown_lock_is_discovered_and_adopted",
    "test_idle_periods.py::test_m3io_served_idle_slower_and_at_100_ms_under_control",
    "test_idle_periods.py::test_scu_data_read_in_turn_rides_on_the_rc_of_the_line_thread",
    "test_layering.py::test_adapters_params_and_codecs_import_nothing_of_app",
    "test_layering.py::test_every_listed_exception_is_still_needed",
    "test_layering.py::test_no_module_imports_a_layer_above_it",
    "test_layering.py::test_nothing_in_app_or_devices_imports_pages",
    "test_layering.py::test_only_the_gate_decides_the_kind_of_a_worker_command",
    "test_logited.py::test_refused_then_taken_back_and_released_on_request",
    "test_logited.py::test_rs485_sends_only_with_the_token_and_passes_it_within_200_ms",
    "test_logited.py::test_rs485_without_the_token_sends_nothing",
    "test_m3io.py::test_addressed_data_refused_without_s8",
    "test_m3io.py::test_addressed_identity_and_customer_data",
    "test_m3io.py::test_fuse_triac_load_states",
    "test_m3io.py::test_hmr_fault_switches_all_three_off",
    "test_m3io.py::test_outputs_drop_in_the_twin_when_the_worker_stops",
    "test_m3io.py::test_p2_in_force_within_1s_of_a_short_reset",
    "test_m3io.py::test_p2_read_back_in_addressed_mode",
    "test_m3io.py::test_p2_resent_after_reset",
    "test_m3io.py::test_software_version_shown_as_an_assumed_decoding",
    "test_m3io.py::test_variant_cannot_be_checked_in_simple_mode",
    "test_m3io.py::test_variant_checked_again_after_the_module_was_gone",
    "test_m3io.py::test_variant_mismatch_refuses_outputs",
    "test_m3io.py::test_watchdog_kept_alive_and_temperatures_flow",
    "test_m3io_outputs.py::test_worker_switches_off_when_the_owner_stops_confirming",
    "test_mcap_export.py::test_live_points_and_frames_of_the_demo_plant",
    "test_mo64_adapter.py::test_twin_tcp_open_pulse_goes_opening_then_open_at_100_percent",
    "test_mo64_page.py::test_error_memory_rows_say_what_each_level_means_with_the_raw_flags_beside",
    "test_mo64_page.py::test_mo64_dead_man_deactivates_the_close_level_of_a_silent_session",
    "test_mo64_page.py::test_mo64_page_shows_the_gate_and_opens_after_the_confirmation",
    "test_mo64_page.py::test_the_shared_sim_card_acts_on_the_twin_through_the_gate",
    "test_mo64_sim.py::test_change_monitoring_sends_unsolicited",
    "test_mo64_sim.py::test_open_level_holds_until_deactivated",
    "test_mo64_sim.py::test_open_pulse_opening_then_open_at_100",
    "test_mo64_sim.py::test_rs485_second_master_passes_token_and_measures_hold",
    "test_mo64_sim.py::test_setting_busy_while_moving_then_syn_ack",
    "test_mo64_strict.py::test_a_unit_that_naks_optional_queries_shows_every_live_value_in_the_api_within_15_s",
    "test_mo64_strict.py::test_rs485_token_is_not_passed_between_syn_and_ack",
    "test_modbus_poll.py::test_running_poll_does_not_starve_the_devices",
    "test_modbus_poll.py::test_windows_take_turns_and_a_silent_unit_does_not_starve_the_others",
    "test_modbus_stale.py::test_sixteen_locks_at_19200_baud_do_not_flap",
    "test_monitor.py::test_can_monitor_page",
    "test_monitor.py::test_modbus_monitor_page",
    "test_mqtt_publisher.py::test_broker_down_at_start_then_stopped_and_restarted",
    "test_mqtt_site.py::test_payload_schema_per_device_type",
    "test_mqtt_site.py::test_view_shows_both_plants_devices_with_live_values",
    "test_pages_devices_hdlock.py::test_save_settings_asks_listing_the_unsaved_changes",
    "test_pages_devices_hdlock.py::test_silent_lock_greys_the_page_and_disables_writes_with_the_reason",
    "test_pages_devices_m3io.py::test_silent_module_disables_switches_with_the_reason_but_not_all_off",
    "test_pages_user.py::test_api_devices",
    "test_pages_user.py::test_line_cycle_time_is_shown_on_the_overview_and_the_monitor",
    "test_pages_user.py::test_loop_lag_is_coloured_by_its_value_not_by_any_stall",
    "test_pages_user.py::test_overview_lists_both_locks_online",
    "test_pages_user.py::test_remove_magnet_asks_for_confirmation_and_cancel_writes_nothing",
    "test_pages_user.py::test_unknown_device_page",
    "test_pages_user.py::test_write_parameter_then_save_settings",
    "test_platform_layering.py::test_no_posix_or_linux_only_call_outside_the_platform_module",
    "test_project.py::test_check_lists_invalid_and_unknown_entries_with_file_and_line",
    "test_record_chain.py::test_a_record_changed_from_outside_is_reported_altered_by_verify_and_the_report",
    "test_record_chain.py::test_archive_verifies_and_one_byte_changed_names_the_file",
    "test_record_signoff.py::test_sign_off_needs_an_engineer_account_and_every_run_stays_in_the_report",
    "test_replace.py::test_identity_read_again_only_when_its_points_change",
    "test_replay_device_frames.py::test_frames_a_device_sends_are_never_replayed_and_each_is_named",
    "test_safety_electrak.py::TestElectrakSafety::runTest",
    "test_safety_hdlock.py::test_set_device_address_counts_only_the_same_lock_as_success",
    "test_safety_hdlock.py::test_set_device_address_refuses_an_id_heard_on_the_bus",
    "test_safety_m3io.py::runTest",
    "test_safety_m3io.py::test_reading_identity_is_no_sign_of_another_master",
    "test_safety_mo64.py::TestMo64Safety::runTest",
    "test_safety_mo64.py::test_the_checkout_asks_that_the_area_is_clear_before_each_motion",
    "test_safety_scu.py::TestScuSafety::runTest",
    "test_scu_adapter.py::test_adapter_against_the_twin_keeps_rc_gaps_below_500_ms_moves_and_stops",
    "test_scu_adapter.py::test_no_answer_marks_offline_naming_cable_dtr_rts_and_baud_rate",
    "test_scu_adapter.py::test_stopped_twin_gives_offline_and_recovery",
    "test_scu_faults.py::test_a_reopening_switches_f20_on_again_when_the_cyclic_definition_gets_no_answer",
    "test_scu_faults.py::test_a_stop_never_acknowledged_with_the_browser_gone_ends_with_the_units_watchdog",
    "test_scu_faults.py::test_one_cse_is_line_noise_and_remembered_as_nothing",
    "test_scu_sim.py::test_a_telegram_cut_short_gets_no_answer_and_the_next_one_does",
    "test_scu_sim.py::test_move_to_remote_position_rises_and_stops_at_the_target",
    "test_scu_sim.py::test_rc_within_500_ms_keeps_remote_mode",
    "test_scu_sim.py::test_watchdog_drops_remote_mode_and_stops_motion_after_500_ms_without_rc",
    "test_security_audit.py::test_a_login_flood_with_huge_names_writes_few_short_rows",
    "test_security_tls.py::test_https_with_secure_session_cookies",
    "test_state_push.py::test_a_device_changing_15_times_a_second_reaches_a_page_as_it_changes",
    "test_state_push.py::test_a_device_nobody_watches_costs_no_call",
    "test_state_push.py::test_a_device_writing_fast_is_pushed_at_a_bounded_rate_and_its_last_value_arrives",
    "test_state_push.py::test_a_page_following_many_devices_runs_them_together",
    "test_state_push.py::test_a_write_reaches_its_watchers_in_the_same_turn_not_on_a_timer",
    "test_tiles.py::test_overview_says_when_a_bus_sheds_frames",
    "test_tiles.py::test_overview_tiles_and_device_pages_mark_stale_values",
    "test_tiles.py::test_plant_view_tiles_from_declarations_then_offline",
    "test_transmit.py::test_cyclic_row_keeps_its_period_and_stops",
    "test_transmit.py::test_cyclic_rows_stop_when_the_session_is_lost",
    "test_transmit_served.py::test_a_digout_the_tools_own_keepalive_overrides_says_so_before_and_after",
}


#: the files that take longest in their phase of the whole suite (``--durations=0`` summed per file, 2026-11-28),
#: longest first: collected first, so the processes that run files side by side do not end with one of them
#: still running alone (a test file runs whole in one process)
LONGEST_FILES = (
    "test_backup.py", "test_pages_roles.py", "test_record_cli.py", "test_checkout_mo64.py", "test_api.py",
    "test_browser_device_pages.py", "test_browser_electrak.py", "test_browser.py", "test_browser_monitor.py",
    "test_browser_admin.py", "test_browser_scu.py", "test_checkout_hdlock.py", "test_browser_m3io.py",
    "test_browser_motion_pages.py", "test_hdlock_adapter.py", "test_backup_page.py", "test_faces_opcua_limits.py",
)


#: the longest tests of the phases whose processes steal work from each other (``--dist worksteal``), with their
#: seconds in the suite's JUnit reports (2026-11-29): each process starts with a share of them (see :class:`_Dealer`)
LONG_TESTS = {
    "test_record_cli.py::test_checkout_sign_and_a_fault_from_the_command_line": 49,
    "test_checkout_mo64.py::test_mo64_checkout_passes_and_an_interrupted_light_barrier_fails_the_close": 26,
    "test_checkout_hdlock.py::test_hdlock_checkout_passes_on_modbus_and_can": 20,
    "test_headless_checkout.py::test_the_person_answers_by_holding_space_and_no_means_nothing_moves": 18,
    "test_checkout_m3io.py::test_m3io_checkout_passes_and_a_blown_fuse_fails_its_step": 14,
    "test_checkout_mo64.py::test_mo64_checkout_without_automatic_closing_and_error_memory": 14,
    "test_safety_mo64.py::test_the_checkout_asks_that_the_area_is_clear_before_each_motion": 14,
    "test_tiles.py::test_overview_tiles_and_device_pages_mark_stale_values": 13,
    "test_record_page_signoff.py::test_a_question_to_act_on_a_simulated_device_offers_the_twin_control_in_the_same_tab": 12,
    "test_api.py::test_m3io_values_then_offline[heater-hmr]": 12,
    "test_checkout_hdlock.py::test_hdlock_checkout_fails_a_lock_that_bolts_with_the_door_open": 11,
    "test_api.py::test_m3io_values_then_offline[heater-hm]": 10,
    "test_pages_roles.py::test_an_engineer_keeps_the_m3io_control_and_the_header_names_the_period[accounts]": 10,
    "test_pages_roles.py::test_an_engineer_keeps_the_m3io_control_and_the_header_names_the_period[loopback]": 10,
    "test_record_chain.py::test_archive_verifies_and_one_byte_changed_names_the_file": 10,
    "test_checkout_mo64.py::test_mo64_checkout_fails_a_light_barrier_that_never_reports": 10,
    "test_record.py::test_values_the_lock_measures_itself_and_a_running_checkout_are_not_drift": 10,
    "test_i18n_checkout.py::test_a_checkout_run_is_worded_in_german_after_a_restart": 10,
    "test_i18n_pages.py::test_the_record_page_in_german_says_a_twin_actions_answer": 9,
    "test_record_cli.py::test_viewers_can_neither_run_checkouts_nor_sign": 9,
    "test_record_chain.py::test_a_record_changed_from_outside_is_reported_altered_by_verify_and_the_report": 9,
    "test_monitor.py::test_can_monitor_page": 9,
    "test_record_signoff.py::test_sign_off_needs_an_engineer_account_and_every_run_stays_in_the_report": 9,
    "test_api.py::test_hdlock_values_with_quality_then_offline[can]": 8,
    "test_tiles.py::test_plant_view_tiles_from_declarations_then_offline": 8,
    "test_api.py::test_electrak_network_values_then_offline": 8,
    "test_checkout_mo64.py::test_mo64_checkout_fails_a_loop_that_never_reports": 8,
    "test_pages_roles.py::test_a_viewer_sees_write_buttons_disabled_with_the_reason": 8,
    # the real-time phase's
    "test_modbus_stale.py::test_sixteen_locks_at_19200_baud_do_not_flap": 14,
    "test_scale_plant.py::test_a_hundred_devices_are_listed_and_keep_alives_stay_on_time": 12,
    "test_scu_adapter.py::test_adapter_against_the_twin_keeps_rc_gaps_below_500_ms_moves_and_stops": 10,
    "test_keepalive_lease.py::test_control_refused_while_another_master_sends_digout": 5,
    "test_scu_adapter.py::test_stopped_twin_gives_offline_and_recovery": 5,
}


def dealt(items: list, workers: int, seconds) -> list:
    """``items`` ordered for ``workers`` processes that steal work: pytest-xdist gives each process its share of the
    list in one piece at the start (the first ``len // workers`` items, then of the rest ...), and a process that is
    done takes half of the rest of the longest queue from its end. A long test at the end of a share would therefore
    start last and run alone; here each share begins with its part of the long tests (``seconds(item)`` > 0, the
    longest to the share with the fewest seconds yet) and is filled up with the others in their order."""
    sizes, left = [], len(items)
    for remaining in range(workers, 0, -1):
        sizes.append(left // remaining)
        left -= sizes[-1]
    long = sorted((item for item in items if seconds(item) > 0), key=seconds, reverse=True)
    shares: list[list] = [[] for _ in range(workers)]
    loads = [0.0] * workers
    for item in long:
        k = min(range(workers), key=lambda n: (loads[n] if len(shares[n]) < sizes[n] else float("inf"), n))
        shares[k].append(item)
        loads[k] += seconds(item)
    taken = {id(item) for item in long}
    others = iter([item for item in items if id(item) not in taken])
    for share, size in zip(shares, sizes, strict=True):
        share.extend(item for _, item in zip(range(size - len(share)), others, strict=False))
    return [item for share in shares for item in share] + list(others)


class _Dealer:
    """Orders the selected tests by :func:`dealt` where processes steal work; after ``-m`` has chosen them."""

    @pytest.hookimpl(trylast=True)
    def pytest_collection_modifyitems(self, config: pytest.Config, items: list[pytest.Item]) -> None:
        worker = getattr(config, "workerinput", None)  # a pytest-xdist worker collects; its options say "no" to dist
        if worker and worker["workercount"] > 1 and _stealing(worker.get("mainargv", [])):
            items[:] = dealt(items, worker["workercount"], lambda item: LONG_TESTS.get(item.nodeid.split("/")[-1], 0))


def _stealing(argv: list[str]) -> bool:
    """The run's command line (as pytest-xdist gives its workers) asks for processes that steal work."""
    return "--dist=worksteal" in argv or any(a == "--dist" and b == "worksteal" for a, b in zip(argv, argv[1:], strict=False))


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Mark every real-browser test ``browser`` (a test_browser_*.py file, one of BROWSER_FILES, or a test
    that uses the ``chromium`` fixture), every test of SLOW_TESTS ``slow``, every test of REALTIME_FILES
    ``realtime`` and a browser test among them ``alone``; the files of LONGEST_FILES first (a stable sort: each file's tests keep their order)."""
    rank = {name: i for i, name in enumerate(LONGEST_FILES)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))
    for item in items:
        name = item.path.name
        if name.startswith("test_browser_") or name in BROWSER_FILES or "chromium" in getattr(item, "fixturenames", ()):
            item.add_marker(pytest.mark.browser)
        node = item.nodeid.split("/")[-1]
        if name in SLOW_TESTS or node in SLOW_TESTS or node.split("[")[0] in SLOW_TESTS:
            item.add_marker(pytest.mark.slow)
        if name in REALTIME_FILES:
            item.add_marker(pytest.mark.realtime)
        if item.get_closest_marker("browser") and item.get_closest_marker("realtime"):
            item.add_marker(pytest.mark.alone)  # a browser held to a real-time bound: a second chromium delays its beats


_MODULE_DATA_DIRS: set[str] = set()


@pytest.fixture(autouse=True)
def _page_events(request: pytest.FixtureRequest) -> None:
    """A browser test's pages are watched; their events start empty for each test (tests/page_events.py)."""
    if request.node.get_closest_marker("browser") is not None:
        page_events.watch_pages()
    page_events.EVENTS.clear()
    page_events.app_logs_began()


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo):
    """A failing test's report says what its pages did besides what it asserts (reloads, lost connections)."""
    outcome = yield
    report = outcome.get_result()
    if report.failed and hasattr(report.longrepr, "addsection"):
        if page_events.EVENTS:
            report.longrepr.addsection("what the test's pages did", "\n".join(page_events.EVENTS[-40:]))
        logged = page_events.app_log_lines()
        if logged:
            report.longrepr.addsection("what its apps logged", "\n".join(logged))


@pytest.fixture(scope="module", autouse=True)
def _module_data_dir(tmp_path_factory: pytest.TempPathFactory) -> Iterator[None]:
    """Each test module its own data folder, set before its module fixtures start an app: the apps of the
    modules that run side by side (one per test process) never share an audit log, a record or a backup
    folder, nor wait on another's database lock."""
    import os

    if _RUN_DATA_DIR is None or os.environ.get("COMMISSION_DATA_DIR") != _RUN_DATA_DIR:
        yield  # a folder chosen by whoever started the tests
        return
    folder = str(tmp_path_factory.mktemp("module-data"))
    _MODULE_DATA_DIRS.add(folder)
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("COMMISSION_DATA_DIR", folder)
        yield


@pytest.fixture(autouse=True)
def _own_data_dir(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> None:
    """Each test its own data folder (its own audit log: no test waits on another's database lock),
    unless a module fixture already chose one for the app it runs."""
    import os

    if os.environ.get("COMMISSION_DATA_DIR") in _MODULE_DATA_DIRS | {_RUN_DATA_DIR}:
        monkeypatch.setenv("COMMISSION_DATA_DIR", str(request.getfixturevalue("tmp_path") / "data"))


async def wait_for(predicate, timeout: float = 5.0, interval: float = 0.05) -> bool:
    """Whether ``predicate`` became true within ``timeout`` s (:func:`webutil.eventually`, as a truth value)."""
    from webutil import eventually

    try:
        await eventually(lambda: bool(predicate()), timeout, interval)
    except AssertionError:
        return False
    return True


def _online(runtime, name: str) -> bool:
    return runtime.store.devices[name].status == "online"


def identified(runtime, name: str) -> bool:
    """Whether the app has read the identity (serial number, ...) of the device ``name`` of ``runtime``."""
    from app import replace

    return replace.live_identity(runtime, name) is not None


@contextlib.asynccontextmanager
async def running_plant(plant: Plant, data_dir: Path | None = None, ready: Iterable[str] = (), within_s: float = 8.0,
                        is_ready: Callable[[object, str], object] = _online, stop_within_s: float = 5.0,
                        simulate: bool = True):
    """The app's runtime on ``plant`` with its twins (unless ``simulate`` is false; its data in ``data_dir``, a folder of its own by default),
    started; it asserts that each device of ``ready`` is ready (``is_ready(runtime, name)``: online by default)
    within ``within_s``; stopped on leaving, within ``stop_within_s``."""
    from app.runtime import Runtime

    runtime = Runtime(plant, simulate=simulate, data_dir=data_dir)
    await runtime.start()
    try:
        for name in ready:
            assert await wait_for(lambda n=name: is_ready(runtime, n), timeout=within_s), name
        yield runtime
    finally:
        await asyncio.wait_for(runtime.stop(), stop_within_s)


@pytest.fixture
def plant() -> Plant:
    return modbus_plant(locks=(("door-1", 1), ("door-2", 2)))


@contextlib.asynccontextmanager
async def alive(worker, *sessions: str, period_s: float = 0.1):
    """Browser ``sessions`` that keep confirming they are alive while inside, every ``period_s`` from now on (what a
    live page does): the worker's dead-man rule stops nothing of theirs."""

    async def beat() -> None:
        while True:
            for session in sessions:
                worker.heartbeat(session)
            await asyncio.sleep(period_s)

    task = asyncio.create_task(beat())
    for session in sessions:
        worker.heartbeat(session)
    try:
        yield
    finally:
        task.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await task


@contextlib.asynccontextmanager
async def closed_after(line, server: asyncio.AbstractServer):
    """Inside, ``line`` talks to ``server``; on leaving, both are closed (the server waited for)."""
    try:
        yield
    finally:
        line.close()
        server.close()
        await server.wait_closed()


@contextlib.asynccontextmanager
async def listening(plant_text: str, channel: str, data_dir: Path):
    """The app without twins on ``plant_text``, started, and a python-can listener on its virtual CAN ``channel``:
    yields ``(runtime, listener)``; both closed on leaving."""
    import can

    from app.runtime import Runtime

    runtime = Runtime(parse_plant(plant_text), simulate=False, data_dir=data_dir)
    await runtime.start()
    listener = can.Bus(interface="virtual", channel=channel, receive_own_messages=False)
    try:
        yield runtime, listener
    finally:
        listener.shutdown()
        await asyncio.wait_for(runtime.stop(), 5)


@pytest.fixture
async def can_rig(tmp_path: Path):
    """The app without twins on :func:`plants.heater_and_lock`'s bus, and a python-can listener on that bus."""
    channel = f"rig-{free_port()}-{time.monotonic_ns()}"
    async with listening(heater_and_lock(channel), channel, tmp_path) as rig:
        yield rig


def one_device_store(name: str):
    """A state store with one HD-Lock ``name`` on line1, seen and never stale, whose Speed is 1.5 rpm (what the
    MQTT, Sparkplug and OPC UA faces publish): ``(store, its state)``."""
    from app.state import StateStore
    from devices.live import DeviceState

    store = StateStore()
    state = DeviceState(name, "hdlock", "line1", stale_after=1e9)
    state.mark_seen()
    state.publish("Speed", 1.5, "rpm")
    store.add(state)
    return store, state


def spy_writes(twin) -> list[tuple[int, int]]:
    """Record every register write that reaches ``twin`` (over the wire, via FC 0x06) in the list returned."""
    writes: list[tuple[int, int]] = []
    original = twin.write

    def recording(address: int, value: int):
        writes.append((address, value))
        return original(address, value)

    twin.write = recording
    return writes


@contextlib.contextmanager
def sim_process(plant_file: Path) -> Iterator[tuple[subprocess.Popen, str]]:
    """`commission sim --plant FILE` in its own process; yields it and its first line of output.

    On leaving, it is stopped with SIGTERM and must exit cleanly (0) within 10 s.
    """
    proc = subprocess.Popen([sys.executable, "-m", "app.cli", "sim", "--plant", str(plant_file)], stdout=subprocess.PIPE, text=True)
    try:
        yield proc, proc.stdout.readline()
    finally:
        proc.terminate()
        try:
            assert proc.wait(timeout=10) == 0
        finally:
            if proc.poll() is None:
                proc.kill()


# -- browser tests ----------------------------------------------------------------------------

CHROMIUM = Path("/usr/bin/chromium")
EXPECT_MS = 15_000  # the longest a browser test's expect() waits for what it asserts, unless it says otherwise


@pytest.fixture(scope="module")
def chromium():
    """Debian's chromium through playwright, launched once per test module.

    Not per session: playwright's sync API holds its event loop as the running one for as long as
    it is open, and the asyncio tests of the other modules could not run meanwhile.
    """
    if not CHROMIUM.exists():
        pytest.skip(f"{CHROMIUM} is not installed")
    from playwright.sync_api import expect, sync_playwright

    # an assertion on a page waits for what it expects up to 15 s (playwright's default: 5 s): a page of an app
    # that shares two cores with other tests and browsers shows a change late, not never
    expect.set_options(timeout=EXPECT_MS)
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
        try:
            yield browser
        finally:
            browser.close()


#: a folder to keep the screenshots the browser tests take for a person to look at (``COMMISSION_TEST_SHOTS=1`` keeps
#: each where its test names it); unset, none is taken: a full page's screenshot costs chromium one to three seconds of
#: CPU, which the suite's other browsers and apps wait for
TEST_SHOTS = os.environ.get("COMMISSION_TEST_SHOTS", "")


def shot(target, path, **options) -> None:
    """``target.screenshot(path=path, **options)`` (a page, a locator) when ``COMMISSION_TEST_SHOTS`` is set."""
    if TEST_SHOTS:
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        target.screenshot(path=str(path), **options)


def inside_viewport(page, locator, timeout: float = 15.0) -> None:
    """Assert that the element of ``locator`` is visible and lies wholly inside the page's viewport. A live table may
    draw its rows anew meanwhile: the element is looked up again until it is rendered (``timeout`` seconds at most: a loaded machine draws late, not never)."""
    end = time.monotonic() + timeout
    box = locator.bounding_box(timeout=timeout * 1000)
    while box is None and time.monotonic() < end:
        page.wait_for_timeout(50)
        box = locator.bounding_box(timeout=max(1000.0, (end - time.monotonic()) * 1000))
    assert box is not None, f"{locator} is not rendered"
    size = page.viewport_size or page.evaluate("({width: window.innerWidth, height: window.innerHeight})")
    assert box["x"] >= 0 and box["y"] >= 0, f"{locator} starts outside the viewport: {box}"
    assert box["x"] + box["width"] <= size["width"] + 0.5, f"{locator} sticks out right of {size['width']} px: {box}"
    assert box["y"] + box["height"] <= size["height"] + 0.5, f"{locator} sticks out below {size['height']} px: {box}"


__all__ = ["CHROMIUM", "CHROMIUM_ARGS", "TEST_SHOTS", "shot", "alive", "closed_after", "free_port", "free_udp_port", "identified", "inside_viewport", "listening", "modbus_plant", "one_device_store", "running_plant", "sim_process", "spy_writes",
           "wait_devices_online", "wait_for"]
