// placeholder until robot sources land
