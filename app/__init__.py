"""G-Style Studio viewer: GL splat renderer, camera control, ImGui panel, engine worker bridge."""
