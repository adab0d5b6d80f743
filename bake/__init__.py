"""The bake: glTF scene -> light maps (irradiance) and cube maps in a bake directory."""
