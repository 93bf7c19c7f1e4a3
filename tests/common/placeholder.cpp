// placeholder until shared test fixtures land
