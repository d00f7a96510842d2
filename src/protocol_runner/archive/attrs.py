"""The archive layout's attribute names: which attributes each kind of object of `archive.h5` (and of the
unit files) carries (docs/archive.md, which tests/archive/test_paths.py checks against this module).

Writers go through `h5util.put_attrs(obj, kind, {...})`, which refuses a name this layout does not give
that kind of object; readers use the constants below. Per-campaign names (`DYNAMIC`) are passed in
`dynamic`.
"""

from __future__ import annotations

# names read back by hand across modules
UNITS = "units"  # every numeric dataset: its unit
DIGEST = "sha256"  # every dataset: its checksum (archive/checksums.py)
CHECKSUM_MARKER = "dataset_checksums"  # root: every dataset has a DIGEST
ATTRIBUTE_DIGESTS = "attribute_sha256"  # every object with attributes: their checksums (JSON name -> digest)
ATTRIBUTE_MARKER = "attribute_checksums"  # root: every object's attributes have an ATTRIBUTE_DIGESTS
UNIT_STEP_ID = "unit_step_id"  # a unit file's step
UNIT_COMPLETE = "unit_complete"  # a unit file written to the end
FILENAME = "filename"  # /protocol, /rig: the file's name
ONLY = "only"  # root: the --only keys
STEP_ID = "step_id"
STATUS = "status"
JOINTS = "joints"
JOINT = "joint"
FACTORS = "factors"
DEVICE_JSON = "device_json"
CONFIGURATIONS = "configurations"  # a comparison's configuration keys
STEP_RESPONSE = ("settled_deg", "settle_error_deg", "time_constant_s")  # a calibration check's response

#: Attributes of each kind of object, in the order docs/archive.md lists them.
ATTRIBUTES: dict[str, tuple[str, ...]] = {
    "root": (
        "protocol_name",
        "protocol_sha256",
        "rig_sha256",
        "schema_version",
        "software_version",
        "mode",
        "seed",
        "created_utc",
        "finished_utc",
        STATUS,
        JOINT,
        ONLY,
        CHECKSUM_MARKER,
        ATTRIBUTE_MARKER,
        "reprocessed_from",
        "reprocessing_protocol_sha256",
        "reprocessing_settings",
    ),
    "dataset": (UNITS, DIGEST),
    "any": (ATTRIBUTE_DIGESTS,),  # every group, dataset and the root that has attributes
    "protocol": (FILENAME,),
    "rig": (FILENAME,),
    "unit": (UNIT_STEP_ID, UNIT_COMPLETE),
    "checklist": (STEP_ID, "title", "items", "brace", "answer", "answered_utc", "automatic"),
    "calibration": (STEP_ID, "verdict", "limits", "message", JOINTS),
    "calibration_joint": (JOINT, "verdict", "step_deg", *STEP_RESPONSE, "message"),
    "configuration": (
        "key",
        "run",
        "set",
        "condition",
        "profile",
        "trajectory_name",
        FACTORS,
        "settings_json",
        DEVICE_JSON,
        "n_trials",
        STATUS,
        JOINTS,
    ),
    "recording": (
        STEP_ID,
        "brace",
        "trajectory",
        "tick_lateness_p99_s",
        "tick_lateness_max_s",
        "input_start_offset_s",
        STATUS,
        JOINTS,
    ),
    "recording_joint": (JOINT, "trajectory"),
    "scaling": ("converged", "target_range_deg", "kept_iteration"),
    "stream": ("segments",),
    "processed": (
        "transition_index0_on",
        "transition_index0_off",
        "subtraction",
        "filter",
        "filter_type",
        "filter_order",
        "filter_cutoff_hz",
        "sample_rate_hz",
        "decimation",
        "coverage",
        "energy_cycles_j",
    ),
    "energy_loss": ("mean_j", "std_j"),
    "bouc_wen": (
        "A",
        "n",
        "beta",
        "rmse_nm",
        "r2",
        "A_std",
        "n_std",
        "beta_std",
        "cv_rmse_nm",
        "n_starts",
        "converged",
        "diverged",
        "scheme",
        "rmse_refined_nm",
        "optimizer_status",
        "optimizer_message",
        "start_rmse_nm",
        "cost_spread",
        "n_interval",
        "param_interval_low",
        "param_interval_high",
        "weakly_identified",
        "weak_reasons",
        "model_energy_j",
        "data_energy_j",
        "model_dissipates",
        "backbone",
        "backbone_note",
        "backbone_coef",
        "backbone_angle_scale_deg",
        "backbone_grid_angle_deg",
        "backbone_grid_torque_nm",
    ),
    "elements": ("applicable", "reason", "target", "rmse_nm", "rmse_all_samples_nm", "elements_json"),
    "element_model": (
        "parameters",
        "value",
        "ci95_low",
        "ci95_high",
        "identified",
        "plausible_low",
        "plausible_high",
        "notes",
        "covariance",
        "values_json",
        "rmse_nm",
        "n_samples",
        "n_eff",
    ),
    "models": (
        "model",
        "k",
        "rmse_nm",
        "heldout_rmse_nm",
        "aic",
        "bic",
        "energy_model_j",
        "energy_data_j",
        "energy_flag",
        "functional",
        "functional_unit",
        "functional_value",
        "functional_ci95_low",
        "functional_ci95_high",
        "bouc_wen_identified",
    ),
    "prediction": (
        "fit_configuration",
        "predict_configuration",
        "joint",
        "note",
        "element_rmse_nm",
        "energy_predicted_j",
        "energy_predicted_ci95_low_j",
        "energy_predicted_ci95_high_j",
        "energy_measured_j",
        "bouc_wen_rmse_nm",
        "bouc_wen_own_rmse_nm",
        "reason",
        "element_source_range_deg",
        "element_target_range_deg",
        "element_beyond_source_deg",
        "element_extrapolated",
        "bouc_wen_source_range_deg",
        "bouc_wen_target_range_deg",
        "bouc_wen_beyond_source_deg",
        "bouc_wen_extrapolated",
    ),
    "spring": (
        "max_preload_mm",
        "zero_offset_deg",
        "rmse_nm",
        "rmse_all_samples_nm",
        "applicable",
        "reason",
        "target",
        "stiffness_n_per_mm",
        "preload_position",
    ),
    "reference": ("source", "title"),
    "comparison": (
        "parameter",
        "section",
        "title",
        CONFIGURATIONS,
        "energy_mean_j",
        "energy_std_j",
        "energy_cycles",
        "max_angle_deg",
        JOINTS,
    ),
    "expectations": ("problems",),
    "expectation": (
        "text",
        "section",
        "metric",
        "unit",
        "relation",
        CONFIGURATIONS,
        "declaration",
        "verdict",
        "reason",
        "p_value",
        "p_adjusted",
        "family",
        "simulator_tuned",
        "depends_on_simulator",
        "dry_run",
        JOINTS,
        JOINT,
    ),
}

#: The per-campaign names some kinds carry besides their fixed ones (documented by pattern).
DYNAMIC: dict[str, str] = {
    "configuration": "`<factor>`, `<factor>.<quantity>`",
    "elements": "`<element>.<parameter>`",
}
