"""JSON Schemas (draft 2020-12) of the files kfcrit reads: system files and sweep files.

The schemas describe the *shape* of a file — keys, nesting, which values are numbers or
expressions; the readers (:mod:`kfcrit.io.systemfile`, :mod:`kfcrit.analysis.sweep.points`) enforce the
rest (matrix sizes, symmetry, ranges of exact values) with one-line errors. ``kfcrit schema
system`` prints :func:`system_schema`; the key reference in ``docs/`` is generated from it.
"""
from __future__ import annotations

from typing import Any

from kfcrit.io.meshfile import mesh_schema

SCHEMA_DIALECT = "https://json-schema.org/draft/2020-12/schema"

NUMBER = {"description": "a number (read exactly from its text) or an exact expression string "
                         "such as \"sqrt(2)/2\", \"2*cos(pi/5)\", \"1/3\"",
          "anyOf": [{"type": "number"}, {"type": "string", "maxLength": 500}]}
MATRIX = {"description": "a list of rows of numbers or expression strings; for Q, R and Sigma0 "
                         "a single value s means s times the identity",
          "anyOf": [{"$ref": "#/$defs/number"},
                    {"type": "array", "minItems": 1,
                     "items": {"type": "array", "minItems": 1,
                               "items": {"$ref": "#/$defs/number"}}}]}
INTEGER = {"description": "an integer (or an exact expression string whose value is one)",
           "anyOf": [{"type": "integer"}, {"type": "string", "maxLength": 500}]}
PROBABILITY = {"$ref": "#/$defs/number", "description": "a probability in [0, 1]"}

CALIBRATED_RADIO = "ieee802154-oqpsk-calibrated"
RADIO_MAPPING_KEYS: dict[str, dict[str, tuple[str, str]]] = {
    "bpsk": {"processing_gain_db": ("number", "processing gain G (dB), in [-60, 60]; "
                                    "default 0")},
    CALIBRATED_RADIO: {
        "sensitivity_dbm": ("number", "required: the receiver sensitivity S (dBm) at "
                            "reference_per"),
        "reference_per": ("number", "packet error rate of the sensitivity test, in (0, 0.5]; "
                          "default 0.01"),
        "reference_psdu_bytes": ("integer", "PSDU length of the sensitivity test (1 to 127 "
                                 "bytes); default 20")},
}
"""The keys a ``radio:`` mapping may set besides ``model``, per radio model, as (type,
meaning). Every other radio (the ideal ``ieee802154-oqpsk-2450`` and each datasheet profile)
takes ``model`` alone; what ``kfcrit radios`` prints beyond these keys (formula, source, frame,
datasheet, calibrated losses) describes the model and cannot be set."""
RADIO_REQUIRED_KEYS: dict[str, tuple[str, ...]] = {CALIBRATED_RADIO: ("sensitivity_dbm",)}


def _object(properties: dict[str, Any], required: list[str], description: str) -> dict[str, Any]:
    return {"type": "object", "description": description, "properties": properties,
            "required": required, "additionalProperties": False}


def channel_defs() -> dict[str, Any]:
    """Schemas of the channel models (``channel.model`` selects one)."""
    num = {"$ref": "#/$defs/number"}
    integer = {"$ref": "#/$defs/integer"}
    bernoulli = _object({"model": {"const": "bernoulli"},
                         "arrival_probability": {**PROBABILITY,
                                                 "description": "P(packet arrives), i.i.d."}},
                        ["model", "arrival_probability"], "i.i.d. packet losses")
    ge = _object({"model": {"const": "gilbert-elliott"},
                  "failure_rate": {**num, "description": "P(lost next | received now), in (0, 1]"},
                  "recovery_rate": {**num, "description": "P(received next | lost now), in (0, 1]"}},
                 ["model", "failure_rate", "recovery_rate"],
                 "bursty (two-state Markov) packet losses")
    trace = _object({"model": {"const": "trace"},
                     "path": {"type": "string", "description": "the trace file, relative to "
                              "the system file"},
                     "format": {"enum": ["binary", "sequence-numbers", "receive-log"],
                                "description": "binary: one 0/1 per period (default); "
                                               "sequence-numbers: the received packets' numbers; "
                                               "receive-log: arrival times in seconds, optionally "
                                               "with a sensor column"},
                     "period_s": {**num, "description": "receive-log: sampling period T in "
                                                        "seconds (required)"},
                     "start_s": {**num, "description": "receive-log: start of period 0 "
                                                       "(default 0)"},
                     "periods": {**integer, "description": "receive-log: number of periods "
                                                           "(default: up to the last arrival)"},
                     "sensor": {"type": "string", "description": "receive-log with a sensor "
                                                                 "column: whose arrivals"},
                     "first": {**integer, "description": "sequence-numbers: first number sent "
                                                         "(default: the first in the file)"},
                     "last": {**integer, "description": "sequence-numbers: last number sent "
                                                        "(default: the last in the file)"},
                     "confidence": {**num, "description": "confidence c in (0, 1) of the verdict "
                                                          "on the fit's confidence region "
                                                          "(default 0.95)"}},
                    ["model", "path"], "a measured packet trace (theory §14)")
    path_loss = {"type": "object", "description": "median path loss and log-normal shadowing",
                 "properties": {
                     "model": {"enum": ["log-distance", "free-space"]},
                     "exponent": {**num, "description": "path-loss exponent n (log-distance)"},
                     "reference_distance_m": {**num, "description": "d0 in metres (default 1)"},
                     "reference_loss_db": {**num, "description": "PL(d0) in dB"},
                     "frequency_hz": {**num, "description": "carrier frequency (free space)"},
                     "shadowing_sigma_db": {**num, "description": "σ of log-normal shadowing"},
                     "shadowing": {"enum": ["per-link", "per-packet", "time-correlated"],
                                   "description": "one shadowing draw per link, per packet, "
                                                  "or a correlated process in time"}},
                 "required": ["model"], "additionalProperties": False}
    noise = _object({"noise_floor_dbm": {**num, "description": "noise floor (dBm)"},
                     "noise_figure_db": {**num, "description": "receiver noise figure (dB)"},
                     "bandwidth_hz": {**num, "description": "noise bandwidth (Hz)"},
                     "temperature_k": {**num, "description": "noise temperature (K)"},
                     "interference_dbm": {**num, "description": "interference power (dBm)"}},
                    [], "noise floor, or thermal noise from bandwidth and noise figure")
    radio = {"description": "a radio model name (see `kfcrit radios`), or a mapping with "
                            "`model` and the keys that model can set (`channel.radio.*` below)",
             "anyOf": [{"type": "string"}, {"$ref": "#/$defs/radio_mapping"}]}
    link = _object({"model": {"const": "link-budget"}, "radio": radio,
                    "tx_power_dbm": {**num, "description": "transmit power (dBm)"},
                    "distance_m": {**num, "description": "transmitter–receiver distance (m)"},
                    "packet_bytes": {**integer, "description": "application payload per "
                                     "packet (bytes)"},
                    "path_loss": path_loss, "noise": noise,
                    "antenna_gain_db": {**num, "description": "total antenna gain (dB)"},
                    "margin_db": {**num, "description": "link margin the policy requires (dB)"},
                    "max_outage": {**num, "description": "largest shadowing outage the policy "
                                   "allows, in [0, 0.5]"},
                    "max_retries": {**integer, "description": "MAC retransmissions per sample "
                                    "(0 to 7 for 802.15.4): arrival 1 − PER^(k+1)"},
                    "mac_overhead_bytes": {**integer, "description": "MAC header + FCS bytes added "
                                           "to the payload (default: the radio's frame, 11 for "
                                           "802.15.4)"},
                    "per_over": {"enum": ["ppdu", "psdu"],
                                 "description": "bits the packet error rate covers: ppdu "
                                 "(default; PHY header + PSDU, as ns-3's lr-wpan model) or "
                                 "psdu (MAC header + payload + FCS only)"},
                    "fading_per_attempt": {"enum": ["shared", "independent", "correlated"],
                                           "description": "shared (default): the retries of "
                                           "one period see the period's shadowing value; "
                                           "independent: redrawn per attempt (per-packet "
                                           "shadowing only), arrival 1 − E[PER]^(k+1); correlated: a "
                                           "Gauss–Markov value per attempt (needs "
                                           "coherence_time_s)"},
                    "coherence_time_s": {"type": "number", "exclusiveMinimum": 0,
                                         "maximum": 1e6,
                                         "description": "with fading_per_attempt: correlated, "
                                         "the shadowing coherence time T_c (s): consecutive "
                                         "attempts are correlated by exp(-Delta/T_c)"},
                    "fading": _object({
                        "model": {"enum": ["none", "rayleigh", "nakagami"],
                                  "description": "none (default), rayleigh (m = 1) or "
                                  "nakagami: the SNR of each attempt is Gamma(m, mean/m) around "
                                  "the mean SNR, redrawn per attempt"},
                        "m": {**num, "description": "Nakagami shape m >= 0.5 (nakagami only)"}},
                        ["model"], "fast fading redrawn per attempt: the attempt PER is "
                        "E[PER(gamma)] (exact quadrature); shadowing sets the mean SNR"),
                    "shadowing_correlation": _object({
                        "sample_period_s": {**num, "description": "sampling period of the filter"},
                        "coherence_time_s": {**num, "description": "shadowing coherence time"},
                        "correlation_distance_m": {**num, "description": "shadowing "
                                                   "decorrelation distance (Gudmundson)"},
                        "speed_mps": {**num, "description": "node speed"}},
                        ["sample_period_s"], "time correlation of the shadowing (with "
                        "path_loss.shadowing: time-correlated), turned into a Gilbert–Elliott "
                        "chain")},
                   ["model", "radio", "tx_power_dbm", "distance_m", "packet_bytes", "path_loss",
                    "noise"], "a radio link: transmit power, distance, packet size, path loss")
    return {"bernoulli": bernoulli, "gilbert_elliott": ge, "trace": trace, "link_budget": link,
            "radio_mapping": radio_mapping_schema(),
            "channel": {"description": "the packet channel of the operating point",
                        "oneOf": [{"$ref": f"#/$defs/{k}"} for k in
                                  ("bernoulli", "gilbert_elliott", "trace", "link_budget")]}}


def radio_mapping_schema() -> dict[str, Any]:
    """Schema of ``radio: {model: NAME, ...}``: the keys of :data:`RADIO_MAPPING_KEYS`, each
    allowed only with its model (``if``/``then`` per model; any other model takes ``model``
    alone)."""
    props: dict[str, Any] = {"model": {"type": "string", "description": "the radio model "
                                       "(`kfcrit radios` lists them)"}}
    rules: list[dict[str, Any]] = []
    for model, keys in RADIO_MAPPING_KEYS.items():
        for key, (kind, meaning) in keys.items():
            props[key] = {"$ref": f"#/$defs/{kind}", "description": f"{meaning} "
                          f"(`model: {model}` only)"}
        rules.append({"if": {"properties": {"model": {"const": model}}, "required": ["model"]},
                      "then": {"propertyNames": {"enum": ["model", *keys]},
                               "required": ["model", *RADIO_REQUIRED_KEYS.get(model, ())]}})
    rules.append({"if": {"properties": {"model": {"not": {"enum": list(RADIO_MAPPING_KEYS)}}}},
                  "then": {"propertyNames": {"const": "model"}}})
    return {"type": "object", "description": "a radio with parameters", "properties": props,
            "required": ["model"], "additionalProperties": False, "allOf": rules}


def links_schema() -> dict[str, Any]:
    """Schema of a network file's ``links:``: link-budget keys merged into every sensor's
    channel (all but ``distance_m``, which is per sensor)."""
    link = channel_defs()["link_budget"]
    props = {k: v for k, v in link["properties"].items() if k != "distance_m"}
    return _object(props, [], "defaults merged into every sensor's link-budget channel: any "
                   "link-budget key except distance_m (per sensor: its channel's distance_m or "
                   "position_m); a sensor's own channel keys take precedence")


def loop_schema(mat: dict[str, Any]) -> dict[str, Any]:
    """JSON Schema of the ``loop:`` section (a closed loop, docs/theory.md §12)."""
    return _object({
        "B": {**mat, "description": "input matrix (n × m_u), exact entries like A"},
        "W": {**mat, "description": "state weight of the cost (n × n, PSD; default identity)"},
        "U": {**mat, "description": "input weight of the cost (m_u × m_u, PD; default "
                                    "identity)"},
        "channel": {"$ref": "#/$defs/channel",
                    "description": "the actuation link (controller → actuator), any model"},
        "acknowledged": {"type": "boolean", "description": "true: TCP-like (acknowledged "
                         "actuation, default); false: UDP-like"},
        "on_loss": {"enum": ["zero", "hold"], "description": "input applied when a control "
                    "packet is lost: zero (default) or the last applied input"},
        "estimator_gain": {**mat, "description": "fixed estimator gain K (n × m, filter "
                           "form); with controller_gain"},
        "controller_gain": {**mat, "description": "fixed controller gain L (m_u × n), "
                            "u = L x̂; with estimator_gain"}},
        ["B", "channel"], "a closed loop over the sensing link (channel:) and an actuation "
        "link (docs/theory.md §12)")


def system_schema() -> dict[str, Any]:
    """JSON Schema of a system file."""
    num = {"$ref": "#/$defs/number"}
    mat = {"$ref": "#/$defs/matrix"}
    requirements = _object({
        "max_error_trace": {**num, "description": "M of the tail requirement P(tr P > M) ≤ α"},
        "max_tail_probability": {**PROBABILITY, "description": "α of the tail requirement"},
        "max_mean_error_trace": {**num, "description": "L of the accuracy requirement "
                                 "lim E[tr P] ≤ L"},
        "max_cost": {**num, "description": "limit of the closed loop's average cost J "
                     "(with loop:; docs/theory.md §12)"}}, [], "design requirements")
    continuous = _object({
        "A": {**mat, "description": "continuous-time state matrix A_c (n × n): dx = A_c x dt + dw"},
        "Q": {**mat, "description": "spectral density Q_c of the process noise w (n × n, PSD)"}},
        ["A", "Q"], "continuous-time model, sampled with a zero-order hold: A = e^{A_c T}, Q = "
        "∫_0^T e^{A_c s} Q_c e^{A_c' s} ds (exact for rational eigenvalues, e.g. integrator "
        "chains; certified floats otherwise); instead of A and Q")
    props = {"name": {"type": "string", "minLength": 1, "description": "name of the system"},
             "description": {"type": "string", "description": "free text"},
             "A": {**mat, "description": "state matrix (n × n); required unless continuous: "
                                         "is given"},
             "C": {**mat, "description": "output matrix (m × n)"},
             "Q": {**mat, "description": "process-noise covariance (n × n, PSD); required "
                                         "unless continuous: is given"},
             "R": {**mat, "description": "measurement-noise covariance (m × m, PD); for a "
                                         "continuous-time model, the discrete covariance of "
                                         "the sampled sensor"},
             "continuous": continuous,
             "sampling_time": {**num, "description": "sampling time T > 0 (seconds) of "
                                                     "continuous:"},
             "Sigma0": {**mat, "description": "initial covariance (default identity)"},
             "channel": {"$ref": "#/$defs/channel"},
             "requirements": {"$ref": "#/$defs/requirements"},
             "sensors": {"type": "array", "minItems": 1, "items": {"$ref": "#/$defs/sensor"},
                         "description": "several sensors, each over its own link (instead of "
                                        "C, R, channel; docs/theory.md §9)"},
             "links": links_schema(),
             "sink_position_m": {"type": "array", "items": num,
                                 "description": "position of the estimator (with the sensors' "
                                                "position_m: distances)"},
             "R_cross": {**mat, "description": "covariance of all sensors' stacked noise "
                                               "(default: independent sensors)"},
             "mesh": mesh_schema(num, mat),
             "loop": loop_schema(mat)}
    sensor = _object({"name": {"type": "string", "description": "unique name of the sensor"},
                      "C": {**mat, "description": "the sensor's rows of C (m_i × n)"},
                      "R": {**mat, "description": "the sensor's noise covariance (m_i × m_i)"},
                      "channel": {"description": "the sensor's channel: a full channel mapping, "
                                                 "or (with links:) the link-budget keys that "
                                                 "differ from the defaults",
                                  "anyOf": [{"$ref": "#/$defs/channel"}, {"type": "object"}]},
                      "position_m": {"type": "array", "items": num,
                                     "description": "position (replaces the channel's "
                                                    "distance_m, with sink_position_m)"}},
                     ["name", "C", "R"], "one sensor of a network")
    defs = {"number": NUMBER, "integer": INTEGER, "matrix": MATRIX,
            "requirements": requirements, "sensor": sensor,
            **channel_defs()}
    discrete = {"required": ["A", "Q"],
                "not": {"anyOf": [{"required": ["continuous"]}, {"required": ["sampling_time"]}]}}
    sampled = {"required": ["continuous", "sampling_time"],
               "not": {"anyOf": [{"required": ["A"]}, {"required": ["Q"]}]}}
    one_sensor = {"required": ["C", "R"], "not": {"anyOf": [
        {"required": ["sensors"]}, {"required": ["links"]}, {"required": ["R_cross"]},
        {"required": ["mesh"]}]}}
    network = {"required": ["sensors", "A", "Q"], "not": {"anyOf": [
        {"required": ["C"]}, {"required": ["R"]}, {"required": ["channel"]},
        {"required": ["continuous"]}, {"required": ["mesh"]}]}}
    mesh = {"required": ["mesh", "A", "Q"], "not": {"anyOf": [
        {"required": [k]} for k in ("C", "R", "channel", "sensors", "links", "continuous",
                                    "sampling_time", "sink_position_m", "R_cross")]}}
    return {"$schema": SCHEMA_DIALECT, "$id": "https://kfcrit.invalid/schema/system.json",
            "title": "kfcrit system file", "type": "object", "properties": props,
            "required": ["name"], "additionalProperties": False,
            "oneOf": [{"allOf": [one_sensor, {"oneOf": [discrete, sampled]}]}, network, mesh],
            "$defs": defs}


def sweep_schema() -> dict[str, Any]:
    """JSON Schema of a sweep file."""
    values = {"description": "the parameter's values: a list (`[20, 40, 116]`; words such as "
                             "radio names where the base value is a word), one value, or a "
                             "range `{start, stop, num}` / `{start, stop, step}` (keys below)",
              "anyOf": [{"type": "array", "minItems": 1, "items": {"$ref": "#/$defs/number"}},
                        {"$ref": "#/$defs/number"},
                        {"type": "object", "properties": {
                            "start": {"$ref": "#/$defs/number",
                                      "description": "first value of a range"},
                            "stop": {"$ref": "#/$defs/number",
                                     "description": "last value (included)"},
                            "num": {"type": "integer", "description": "number of values"},
                            "step": {"$ref": "#/$defs/number",
                                     "description": "spacing (instead of num)"},
                            "scale": {"enum": ["linear", "log"],
                                      "description": "linear (default) or log spacing"}},
                         "required": ["start", "stop"], "additionalProperties": False}]}
    props = {"name": {"type": "string"}, "description": {"type": "string"},
             "system": {"description": "the base system: a system-file path (relative to the "
                                       "sweep file) or an inline system mapping",
                        "anyOf": [{"type": "string"}, {"type": "object"}]},
             "tolerance": {"$ref": "#/$defs/number"},
             "grid": {"type": "object", "description": "parameter path → values; the grid is "
                                                       "their product. Paths: channel.KEY[.KEY…], "
                                                       "sensors.NAME.channel.KEY[.KEY…], "
                                                       "links.KEY[.KEY…], a matrix entry A[i][j] "
                                                       "(C, Q, R, Sigma0)",
                      "additionalProperties": values},
             "points": {"type": "array", "description": "explicit points: mappings of parameter "
                                                        "path → value",
                        "items": {"type": "object",
                                  "additionalProperties": {"$ref": "#/$defs/number"}}},
             "plot": _object({"x": {"type": "string", "description": "the swept parameter on the "
                                                                   "margin plot's x axis"}},
                             [], "the margin plot")}
    return {"$schema": SCHEMA_DIALECT, "$id": "https://kfcrit.invalid/schema/sweep.json",
            "title": "kfcrit sweep file", "type": "object", "properties": props,
            "required": ["system"], "additionalProperties": False,
            "$defs": {"number": NUMBER}}
