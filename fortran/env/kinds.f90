!> Kinds and small constants shared by every module of pymr.
module pymr_env_kinds
  implicit none
  private
  public :: dp, pi, name_len

  !> Double precision real kind used for every real in pymr.
  integer, parameter :: dp = selected_real_kind(15, 307)
  !> The circle constant.
  real(dp), parameter :: pi = 3.14159265358979323846264338327950288_dp
  !> Length of names (bodies, joints, markers, effects).
  integer, parameter :: name_len = 64
end module pymr_env_kinds
