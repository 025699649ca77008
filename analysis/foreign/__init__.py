"""Your own plant: any FMI 2.0 or 3.0 FMU, model exchange or co-simulation, as the plant of dfwb's analyses."""
