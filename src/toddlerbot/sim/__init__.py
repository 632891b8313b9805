"""MuJoCo simulation backend of the `Robot` interface, and rendering (video, snapshots, viewer)."""
