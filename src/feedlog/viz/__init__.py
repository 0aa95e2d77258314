"""feedlog.viz: see what the machine did, and the main job in one command.

    data = prepare_view(ViewInputs(recording, program_blocks=..., sim_series=..., models=[...]))
    save_view(data, "run.rrd")      # Rerun overlays (columnar, blueprint in code); or log_view(data, stream)
    plot_view(data, "plots/")       # the same overlays as PNG plots

Modules: `prepare` (plot-ready tables), `overlay` (Rerun), `plots` (matplotlib), `colors`, `stages`
(lazy access to the other stages), `sources` (gather what to overlay), `predictions`, `training`,
`pipeline` and `report` (the demo), `cli` (`feedlog view`), `demo` (`feedlog demo`). See docs/viz.md.
"""
